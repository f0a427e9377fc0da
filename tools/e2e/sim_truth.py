#!/usr/bin/env python3
"""Shared by cflib_modes.py, cflib_setpoint.py and cflib_persistent.py: start `cfnav sim --serve` with its stderr in a file, and read
the simulator's truth lines from it (tools/src/sim/serve.rs, module docs "Truth").

The truth never goes over the radio: the checks compare what cflib logged from the drone with what the
simulated body really did. A truth line is

    `  12.345 s  <event>  estimate (x, y, z) truth (x, y, z)`

with <event> `state 207 LinkLost`, `flying`, `landed` or `link lost: ...`; the time is simulated seconds since
power-on (the log timestamps' clock, in ms), positions are arena frame in metres, the truth's z is its
underside above the floor.
"""

import os
import re
import subprocess
import sys
import time
import tomllib

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from wait_for_sim import answers_scan_probe  # noqa: E402

_NUM = r"(-?[\d.]+|NaN|inf|-inf)"
TRUTH_LINE = re.compile(
    r"^\s*([\d.]+) s  (.*?)  estimate \(" + ", ".join([_NUM] * 3) + r"\) truth \(" + ", ".join([_NUM] * 3) + r"\)"
)


class TruthEvent:
    def __init__(self, t_s, event, estimate, truth):
        self.t_s = t_s
        self.event = event
        self.estimate = estimate
        self.truth = truth

    def __repr__(self):
        e, p = self.estimate, self.truth
        return (f"{self.t_s:.3f} s {self.event}: estimate ({e[0]:.3f}, {e[1]:.3f}, {e[2]:.3f}) "
                f"truth ({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f})")


class Sim:
    """`cfnav sim --serve --port PORT [--speed SPEED] [--world FILE] [EXTRA...]`, stdout and stderr to
    `log_path` (appended to with `append`, e.g. one log over several power cycles); a context manager."""

    def __init__(self, binary, port, speed, log_path, world=None, extra=(), append=False):
        self.cmd = [binary, "sim", "--serve", "--port", str(port)]
        if speed is not None:
            self.cmd += ["--speed", str(speed)]
        if world:
            self.cmd += ["--world", world]
        self.cmd += list(extra)
        self.port = port
        self.log_path = log_path
        self.append = append
        self.proc = None
        self.log = None

    def __enter__(self):
        self.log = open(self.log_path, "a" if self.append else "w")
        self.proc = subprocess.Popen(self.cmd, stdout=self.log, stderr=self.log)
        if not answers_scan_probe(self.port, 60):
            self.proc.kill()
            raise RuntimeError(f"the simulator did not come up: {' '.join(self.cmd)} (log {self.log_path})")
        return self

    def __exit__(self, *exc):
        self.proc.terminate()
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        self.log.close()

    def events(self):
        """Every truth line written so far, in order."""
        out = []
        with open(self.log_path) as f:
            for line in f:
                m = TRUTH_LINE.match(line)
                if m:
                    v = [float(x) for x in m.groups()[2:]]
                    out.append(TruthEvent(float(m.group(1)), m.group(2), v[:3], v[3:]))
        return out

    def wait_event(self, prefix, after_s=-1.0, timeout_s=10.0):
        """The first truth event whose text starts with `prefix` at a simulated time > `after_s`, waiting up
        to `timeout_s` of wall time for the simulator to write it; None if it never comes."""
        deadline = time.monotonic() + timeout_s
        while True:
            for e in self.events():
                if e.event.startswith(prefix) and e.t_s > after_s:
                    return e
            if time.monotonic() > deadline:
                return None
            time.sleep(0.1)


def world_pads(world_file):
    """The pads of a world file: [(centre x, centre y, half size x, half size y, top height)]."""
    with open(world_file, "rb") as f:
        w = tomllib.load(f)
    pads = []
    for p in w.get("pads", []):
        c, s = p["center"], p.get("size", [0.3, 0.3])
        pads.append((c[0], c[1], s[0] / 2, s[1] / 2, p.get("height", 0.0)))
    return pads, w["mission"]["start"]
