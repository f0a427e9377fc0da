#!/usr/bin/env python3
"""Mission modes, link loss and bad writes end to end:
unmodified cflib (PyPI) against `cfnav sim --serve`, a fresh simulator for each case, judged on what cflib logs
and on the simulator's truth (its stderr, tools/e2e/sim_truth.py; never sent over the radio).

Cases (each prints its checks; exit 1 at the end if any failed):
- `bad-writes`: `mission.mode = 3`, `mission.linkLoss = 3` written through `param.set_value` are refused: a
  console line names each, and the value read back from the drone (`request_param_update`) is unchanged.
- `hover`: `mission.mode = 1`, `mission.hoverTime = 2` written, `mission.start = 1` (as the README says); logs
  `mission.state`, `mission.hoverDevXY/Z` and the estimate: states 50 (hold) and 51 (land) seen, the final
  state 100; the logged worst deviations are non-zero and under 10 cm; the drone truly landed within 10 cm
  of where it truly took off. During the hold, `mission.mode = 2` is refused (console line, reads back 1).
- `explore`: `mission.mode = 2`, `mission.coverage = 0.35`: `mission.covered` logged rising to ≥ 0.35, states
  60/61 seen, final state 100, the drone truly on the home pad's top.
- `link-loss-1` / `link-loss-2`: `mission.linkLoss` = 1 / 2, `mission.linkTimeout = 1`, a round-trip mission
  started; once it navigates (state 11) 0.5 m from home, cflib closes the link (nothing more is sent). The
  simulator must see the timeout about 1 s of simulated time after the last packet; cflib reconnects after
  3 s and reads where the drone is: policy 1 ends in state 207, truly landed within 0.3 m of where the link
  timed out and its estimate within 0.5 m of the last one logged before the silence; policy 2 ends in 208,
  truly on the home pad's top, the estimate within 0.2 m of home.

Usage: cflib_modes.py --sim PATH/TO/cfnav [--port 19856] [--speed 3] [--out DIR] [CASE ...]
`--expect-wrong` runs the cases with deliberately wrong expectations (every case must then fail: a check that
cannot fail is no check).
"""

import argparse
import math
import os
import struct
import sys
import threading
import time

import cflib.crtp
from cflib.crazyflie import Crazyflie
from cflib.crazyflie.log import LogConfig
from cflib.crazyflie.syncCrazyflie import SyncCrazyflie

from sim_truth import Sim, world_pads

HERE = os.path.dirname(os.path.abspath(__file__))
WORLD = os.path.join(HERE, "..", "..", "worlds", "default.toml")
CASES = ["bad-writes", "hover", "explore", "link-loss-1", "link-loss-2"]

failures = []
WRONG = False  # --expect-wrong


def check(name, ok, detail):
    """Prints and records one check; with --expect-wrong the expectation was inverted by the caller."""
    print(f"{'ok  ' if ok else 'FAIL'} {name}: {detail}", flush=True)
    if not ok:
        failures.append(name)
    return ok


class Link:
    """One cflib connection: console text, a log block of mission and estimate variables, parameter reads."""

    def __init__(self, uri, extra_log=()):
        self.uri = uri
        self.extra_log = list(extra_log)
        self.console = []
        self.rows = []  # (log timestamp ms, {name: value})
        self.lock = threading.Lock()

    def __enter__(self):
        self.scf = SyncCrazyflie(self.uri, cf=Crazyflie(rw_cache=None))
        self.scf.open_link()
        self.cf = self.scf.cf
        self.cf.console.receivedChar.add_callback(self._console)
        conf = LogConfig(name="mission", period_in_ms=50)
        for v in ["mission.state", "stateEstimate.x", "stateEstimate.y", "stateEstimate.z"] + self.extra_log:
            conf.add_variable(v)
        conf.data_received_cb.add_callback(self._row)
        self.cf.log.add_config(conf)
        conf.start()
        self.conf = conf
        self.wait(lambda: self.rows, 5.0)
        return self

    def __exit__(self, *exc):
        self.close()

    def close(self):
        """Closes the link: from here on cflib sends nothing (no pings, no log packets)."""
        if self.scf is not None:
            self.scf.close_link()
            self.scf = None

    def _console(self, text):
        with self.lock:
            self.console.append(text)

    def _row(self, ts, data, _conf):
        with self.lock:
            self.rows.append((ts, dict(data)))

    def last(self):
        with self.lock:
            return self.rows[-1] if self.rows else (0, {})

    def console_text(self):
        with self.lock:
            return "".join(self.console)

    def states(self):
        with self.lock:
            return [r[1]["mission.state"] for r in self.rows]

    def wait(self, cond, timeout_s):
        deadline = time.monotonic() + timeout_s
        while not cond():
            if time.monotonic() > deadline:
                return False
            time.sleep(0.05)
        return True

    def wait_final(self, timeout_s):
        """Waits for a final mission state (100 or ≥ 200); returns it, or None."""
        self.wait(lambda: self.last()[1].get("mission.state", 0) >= 100, timeout_s)
        s = self.last()[1].get("mission.state", 0)
        return s if s >= 100 else None

    def read_param(self, name, timeout_s=3.0):
        """The value the drone reports now (a fresh read, not cflib's cache of the last write)."""
        got = threading.Event()
        box = []
        group, short = name.split(".")

        def cb(complete_name, value):
            if complete_name == name:
                box.append(value)
                got.set()

        self.cf.param.add_update_callback(group=group, name=short, cb=cb)
        self.cf.param.request_param_update(name)
        got.wait(timeout_s)
        self.cf.param.remove_update_callback(group=group, name=short, cb=cb)
        return box[-1] if box else None

    def set_param(self, name, value, settle_s=0.5):
        self.cf.param.set_value(name, value)
        time.sleep(settle_s)


def refused(link, name, bad, good, wrong):
    """Writes `bad` to `name` and checks the refusal: a console line naming it, the value unchanged (`good`)."""
    before = len(link.console_text())
    link.set_param(name, bad)
    link.wait(lambda: f"param {name} refused" in link.console_text()[before:], 2.0)
    line = [ln for ln in link.console_text()[before:].splitlines() if name in ln]
    check(f"{name} = {bad}: console line", bool(line), repr(line[:1]))
    value = link.read_param(name)
    expect = bad if wrong else good
    check(f"{name} = {bad}: read back", value is not None and float(value) == float(expect),
          f"reads {value}, expected {expect}")


def case_bad_writes(uri, sim, pads, start):
    with Link(uri) as link:
        for name in ("mission.mode", "mission.linkLoss"):
            refused(link, name, 3, 0, WRONG)


def case_hover(uri, sim, pads, start):
    with Link(uri, ["mission.hoverDevXY", "mission.hoverDevZ"]) as link:
        link.set_param("mission.mode", 1)
        link.set_param("mission.hoverTime", 2.0)
        check("mission.mode written", link.read_param("mission.mode") == "1" or
              str(link.read_param("mission.mode")) == "1", f"reads {link.read_param('mission.mode')}")
        link.set_param("mission.start", 1, settle_s=0.0)
        link.wait(lambda: link.last()[1]["mission.state"] == 50, 20.0)
        # During the hold: a mode change is refused and nothing changes.
        refused(link, "mission.mode", 2, 1, False)
        final = link.wait_final(40.0)
        states = set(link.states())
        check("hover: phases", {50, 51} <= states, f"states seen {sorted(states)}")
        want = 202 if WRONG else 100
        check("hover: final state", final == want, f"final {final}, expected {want}")
        d = link.last()[1]
        dxy, dz = d["mission.hoverDevXY"], d["mission.hoverDevZ"]
        limit = 0.005 if WRONG else 0.10
        check("hover: worst deviation logged", 0.0 < dxy <= limit and 0.0 < dz <= limit,
              f"hoverDevXY {dxy:.3f} m, hoverDevZ {dz:.3f} m (limit {limit} m)")
    took_off = sim.wait_event("flying")
    landed = sim.wait_event("state 100") or sim.wait_event("state 2")
    if check("hover: truth lines", took_off is not None and landed is not None, f"{took_off}; {landed}"):
        off = math.dist(took_off.truth[:2], landed.truth[:2])
        limit = 0.001 if WRONG else 0.10
        check("hover: truly landed where it took off", off <= limit, f"{off:.3f} m (limit {limit} m)")


def on_pad(truth, pad, tol_z=0.03):
    cx, cy, hx, hy, top = pad
    return abs(truth[0] - cx) <= hx and abs(truth[1] - cy) <= hy and abs(truth[2] - top) <= tol_z


def case_explore(uri, sim, pads, start):
    with Link(uri, ["mission.covered"]) as link:
        link.set_param("mission.mode", 2)
        link.set_param("mission.coverage", 0.35)
        link.set_param("mission.start", 1, settle_s=0.0)
        final = link.wait_final(60.0)
        with link.lock:
            covered = [r[1]["mission.covered"] for r in link.rows]
        states = set(link.states())
        check("explore: phases", 60 in states or 61 in states, f"states seen {sorted(states)}")
        want = 0.9 if WRONG else 0.35
        steps = sorted(set(covered))
        check("explore: coverage logged rising to the target",
              covered[0] < 0.2 and len(steps) >= 3 and covered == sorted(covered) and max(covered) >= want,
              f"mission.covered from {covered[0]:.2f} to {max(covered):.2f} in {len(steps) - 1} rises "
              f"(target {want})")
        check("explore: final state", final == 100, f"final {final}")
    end = sim.wait_event("state 100") or sim.wait_event("state 2")
    home = pads[0] if not WRONG else pads[1]
    if check("explore: truth line", end is not None, f"{end}"):
        check("explore: truly on the home pad", on_pad(end.truth, home), f"{end}, pad {home}")


def case_link_loss(policy):
    def run(uri, sim, pads, start):
        link = Link(uri)
        with link:
            link.set_param("mission.linkLoss", policy)
            link.set_param("mission.linkTimeout", 1.0)
            check(f"link-loss-{policy}: written", str(link.read_param("mission.linkLoss")) == str(policy),
                  f"mission.linkLoss reads {link.read_param('mission.linkLoss')}")
            link.set_param("mission.start", 1, settle_s=0.0)
            flying = link.wait(lambda: link.last()[1]["mission.state"] == 11 and
                               math.dist((link.last()[1]["stateEstimate.x"], link.last()[1]["stateEstimate.y"]),
                                         start) > 0.5, 30.0)
            check(f"link-loss-{policy}: navigating", flying, f"{link.last()}")
            ts_silent, at = link.last()
            link.close()
        pos_silent = (at["stateEstimate.x"], at["stateEstimate.y"])
        print(f"     link closed at {ts_silent / 1000:.3f} s (simulated), estimate ({pos_silent[0]:.2f}, "
              f"{pos_silent[1]:.2f}, {at['stateEstimate.z']:.2f})", flush=True)
        time.sleep(3.0)
        fired = sim.wait_event("link lost", after_s=ts_silent / 1000, timeout_s=5.0)
        if check(f"link-loss-{policy}: the simulator saw the timeout", fired is not None, f"{fired}"):
            late = fired.t_s - ts_silent / 1000
            check(f"link-loss-{policy}: timeout after mission.linkTimeout", 0.9 <= late <= 1.6,
                  f"{late:.3f} s after the last log packet cflib received")
        with Link(uri) as again:
            final = again.wait_final(60.0)
            d = again.last()[1]
            est = (d["stateEstimate.x"], d["stateEstimate.y"])
        want = {1: 207, 2: 208}[policy]
        if WRONG:
            want = 100
        check(f"link-loss-{policy}: final state read after reconnecting", final == want,
              f"final {final}, expected {want}")
        end = sim.wait_event(f"state {final}") if final else None
        if not check(f"link-loss-{policy}: truth lines", end is not None and fired is not None, f"{end}"):
            return
        if policy == 1:
            moved = math.dist(end.truth[:2], fired.truth[:2])
            limit = 0.01 if WRONG else 0.30
            check("link-loss-1: truly landed where the link timed out", moved <= limit and end.truth[2] < 0.03,
                  f"{moved:.3f} m from the timeout point (limit {limit} m), truth z {end.truth[2]:.3f}")
            # It flies on for mission.linkTimeout (1 s) at up to mission.speed (0.5 m/s) after the last packet,
            # and the last log cflib got is up to one log period older: 0.7 m.
            off = math.dist(est, pos_silent)
            check("link-loss-1: estimate near where the link went silent", off <= 0.7,
                  f"estimate ({est[0]:.2f}, {est[1]:.2f}), {off:.2f} m from the last one before the silence")
        else:
            home = pads[1] if WRONG else pads[0]
            check("link-loss-2: truly on the home pad", on_pad(end.truth, home), f"{end}, pad {home}")
            off = math.dist(est, start)
            check("link-loss-2: estimate at home", off <= 0.2, f"estimate ({est[0]:.2f}, {est[1]:.2f}), {off:.2f} m")
    return run


def main():
    global WRONG
    ap = argparse.ArgumentParser()
    ap.add_argument("--sim", required=True, help="the cfnav binary (release build)")
    ap.add_argument("--port", type=int, default=19856)
    ap.add_argument("--speed", type=float, default=3.0)
    ap.add_argument("--out", default="target/e2e-modes")
    ap.add_argument("--timeout", type=float, default=170.0, help="wall-clock bound for everything, s")
    ap.add_argument("--expect-wrong", action="store_true")
    ap.add_argument("cases", nargs="*", default=CASES)
    args = ap.parse_args()
    WRONG = args.expect_wrong
    for c in args.cases:
        if c not in CASES:
            ap.error(f"unknown case {c}: {CASES}")
    t = threading.Timer(args.timeout, lambda: (print("FAIL: timeout", flush=True), os._exit(1)))
    t.daemon = True
    t.start()
    os.makedirs(args.out, exist_ok=True)
    cflib.crtp.init_drivers()
    pads, start = world_pads(WORLD)
    runs = {"bad-writes": case_bad_writes, "hover": case_hover, "explore": case_explore,
            "link-loss-1": case_link_loss(1), "link-loss-2": case_link_loss(2)}
    uri = f"udp://127.0.0.1:{args.port}"
    for c in args.cases:
        t0 = time.monotonic()
        print(f"--- {c}", flush=True)
        log = os.path.join(args.out, f"serve-{c}.log")
        n = len(failures)
        try:
            with Sim(args.sim, args.port, args.speed, log, world=WORLD) as sim:
                runs[c](uri, sim, pads, start)
        except Exception as e:  # a cflib error is a failed case, not a crash of the run
            check(f"{c}: ran", False, f"{type(e).__name__}: {e}")
        print(f"    {c}: {'passed' if len(failures) == n else 'FAILED'} in {time.monotonic() - t0:.1f} s wall "
              f"(simulator log {log})", flush=True)
    if failures:
        print(f"FAIL: {failures}", flush=True)
        return 1
    print("mission modes, link loss and bad writes: every check passed", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
