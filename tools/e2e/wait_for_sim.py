#!/usr/bin/env python3
"""Waits until `cfnav sim --serve` answers cflib's scan probe (a bare 0xFF datagram) on 127.0.0.1:PORT.

Usage: wait_for_sim.py PORT [SECONDS]   (default 30 s). Exit 0 once it answers, 1 with a message otherwise.
"""
import socket
import sys
import time

port = int(sys.argv[1])
deadline = time.monotonic() + (float(sys.argv[2]) if len(sys.argv) > 2 else 30.0)
while time.monotonic() < deadline:
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.settimeout(0.2)
    try:
        s.sendto(b"\xff", ("127.0.0.1", port))
        s.recv(64)
        sys.exit(0)
    except OSError:
        time.sleep(0.2)
    finally:
        s.close()
sys.exit(f"the simulator does not answer on udp://127.0.0.1:{port}")
