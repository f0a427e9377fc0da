#!/usr/bin/env python3
"""Waits until `cfnav sim --serve` (or `cfnav-pil --serve`) answers cflib's scan probe (a bare 0xFF datagram)
on 127.0.0.1:PORT.

Usage: wait_for_sim.py PORT [SECONDS]   (default 30 s). Exit 0 once it answers, 1 with a message otherwise.
Other scripts import `answers_scan_probe` from here instead of repeating the loop.
"""
import socket
import sys
import time


def answers_scan_probe(port, seconds):
    """True once 127.0.0.1:port answers a bare 0xFF datagram within `seconds` of wall time."""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        s.settimeout(0.2)
        try:
            s.sendto(b"\xff", ("127.0.0.1", port))
            s.recv(64)
            return True
        except OSError:
            time.sleep(0.2)
        finally:
            s.close()
    return False


if __name__ == "__main__":
    port = int(sys.argv[1])
    if not answers_scan_probe(port, float(sys.argv[2]) if len(sys.argv) > 2 else 30.0):
        sys.exit(f"the simulator does not answer on udp://127.0.0.1:{port}")
