#!/usr/bin/env python3
"""A mission started after other flights, on one connection: unmodified cflib (PyPI) against
`cfnav sim --serve` (default world), a fresh simulator for each case, judged on what cflib logs and on the
simulator's truth (its stderr, tools/e2e/sim_truth.py; never sent over the radio). docs/mission-start.md
says what a start does.

Cases (each prints its checks; exit 1 at the end if any failed):
- `hover-after-flights`: HighLevelCommander take off to 0.5 m, go_to 1 m along +x (relative), land, stop;
  MotionCommander take off, land (its take_off writes kalman.resetEstimation); then mission.mode = 1,
  mission.hoverTime = 2, mission.start = 1. Checks: the final state is 100; every state logged is the
  hover test's (0, 1, 10, 50, 51, 100: never a pad search, 12-15); the start did not move the estimate
  (the estimate at state 1 within 2 cm of the one before the start); the drone truly landed within 10 cm of
  where it truly took off for the hover test, about 1 m from the home pad.
- `round-trip-off-pad`: HighLevelCommander take off, go_to 1 m along +x, land, stop; mission.mode = 0,
  mission.start = 1: refused (a console line says where the drone is and how far from the home pad,
  mission.start reads 0 again, the state stays 0, no truth line of a state 1); then the HighLevelCommander
  flies back to mission.startX/Y (absolute go_to), lands, stops; mission.start = 1 again: accepted, the
  final state is 100 and the drone truly rests on the home pad's top.

Usage: cflib_sequence.py --sim PATH/TO/cfnav [--port 19857] [--speed 2] [--out DIR] [CASE ...]
The speed is bounded by MotionCommander: it sends a setpoint every 0.2 s of wall time, and the supervisor
levels out after 0.5 s of simulated time without one (speed 2: 0.4 s). `--expect-wrong` runs the cases with
deliberately wrong expectations (every case must then fail: a check that cannot fail is no check).
"""

import argparse
import math
import os
import sys
import threading
import time

import cflib.crtp
from cflib.positioning.motion_commander import MotionCommander

from cflib_modes import Link
from sim_truth import Sim, world_pads

HERE = os.path.dirname(os.path.abspath(__file__))
WORLD = os.path.join(HERE, "..", "..", "worlds", "default.toml")
CASES = ["hover-after-flights", "round-trip-off-pad"]
HOVER_STATES = {0, 1, 10, 50, 51, 100}

failures = []
WRONG = False  # --expect-wrong
SPEED = 2.0


def check(name, ok, detail):
    print(f"{'ok  ' if ok else 'FAIL'} {name}: {detail}", flush=True)
    if not ok:
        failures.append(name)
    return ok


def sim_sleep(seconds):
    """Sleeps `seconds` of simulated time."""
    time.sleep(seconds / SPEED)


def estimate(link):
    d = link.last()[1]
    return (d["stateEstimate.x"], d["stateEstimate.y"], d["stateEstimate.z"])


def hl_flight(link, to, relative, name):
    """HighLevelCommander: take off to 0.5 m in 2 s, go_to `to` in 3 s, land in 2 s, stop; each step waits
    for the logged estimate to get there (wall time bounded: a loaded machine runs the simulator slower)."""
    hl = link.cf.high_level_commander
    x0, y0, _ = estimate(link)
    target = (x0 + to[0], y0 + to[1]) if relative else to
    hl.takeoff(0.5, 2.0, yaw=None)
    sim_sleep(2.0)
    check(f"{name}: took off", link.wait(lambda: estimate(link)[2] > 0.4, 10.0), f"estimate {estimate(link)}")
    hl.go_to(to[0], to[1], 0.0 if relative else 0.5, 0.0, 3.0, relative=relative, linear=not relative)
    sim_sleep(3.0)
    check(f"{name}: go_to", link.wait(lambda: math.dist(estimate(link)[:2], target) < 0.1, 10.0),
          f"estimate {estimate(link)}, target {target}")
    hl.land(0.0, 2.0)
    sim_sleep(2.0)
    check(f"{name}: landed", link.wait(lambda: estimate(link)[2] < 0.15, 10.0), f"estimate {estimate(link)}")
    sim_sleep(0.5)
    hl.stop()
    sim_sleep(1.0)
    e = estimate(link)
    print(f"     {name}: landed, estimate ({e[0]:.2f}, {e[1]:.2f}, {e[2]:.2f})", flush=True)
    return e


def write_start(link):
    """Writes mission.start = 1; while the supervisor still counts the last landing as flying (its verdict
    trails the touchdown) the drone refuses with "start while flying": wait and write again, as a user
    would. Returns the console text the last write produced."""
    for _ in range(10):
        before = len(link.console_text())
        link.set_param("mission.start", 1, settle_s=0.0)
        link.wait(lambda: link.last()[1].get("mission.state", 0) != 0
                  or "refused" in link.console_text()[before:], 3.0)
        time.sleep(0.3)
        text = link.console_text()[before:]
        if "start while flying" not in text:
            return text
        sim_sleep(1.0)
    return text


def on_pad(truth, pad, tol_z=0.03):
    cx, cy, hx, hy, top = pad
    return abs(truth[0] - cx) <= hx and abs(truth[1] - cy) <= hy and abs(truth[2] - top) <= tol_z


def case_hover_after_flights(uri, sim, pads, start):
    with Link(uri) as link:
        sim_sleep(2.0)  # the estimator settles on the ground (the README's 1 s trigger)
        hl_flight(link, (1.0, 0.0), True, "HighLevelCommander")
        with MotionCommander(link.cf, default_height=0.5):
            time.sleep(1.0)
        time.sleep(1.0)
        before = estimate(link)
        print(f"     MotionCommander: landed, estimate ({before[0]:.2f}, {before[1]:.2f})", flush=True)
        link.set_param("mission.mode", 1)
        link.set_param("mission.hoverTime", 2.0)
        t_start = link.last()[0] / 1000.0
        write_start(link)
        final = link.wait_final(60.0 / SPEED + 20.0)
        states = set(link.states())
        want = 202 if WRONG else 100
        check("hover-after-flights: final state", final == want, f"final {final}, expected {want}")
        allowed = HOVER_STATES - {51} if WRONG else HOVER_STATES
        check("hover-after-flights: only the hover test's states", states <= allowed,
              f"states seen {sorted(states)}, allowed {sorted(allowed)}")
    preflight = sim.wait_event("state   1", after_s=t_start - 1.0)
    if check("hover-after-flights: preflight truth line", preflight is not None, f"{preflight}"):
        moved = math.dist(preflight.estimate[:2], before[:2])
        limit = 0.0 if WRONG else 0.02
        check("hover-after-flights: the start kept the estimate", moved <= limit,
              f"estimate ({preflight.estimate[0]:.3f}, {preflight.estimate[1]:.3f}) at state 1, "
              f"{moved:.3f} m from ({before[0]:.3f}, {before[1]:.3f}) before the start (limit {limit} m)")
    took_off = sim.wait_event("flying", after_s=preflight.t_s if preflight else t_start)
    landed = sim.wait_event("state 100", after_s=t_start) or sim.wait_event("state 2", after_s=t_start)
    if check("hover-after-flights: truth lines", took_off is not None and landed is not None,
             f"{took_off}; {landed}"):
        off = math.dist(took_off.truth[:2], landed.truth[:2])
        limit = 0.001 if WRONG else 0.10
        check("hover-after-flights: truly landed where it took off", off <= limit,
              f"{off:.3f} m (limit {limit} m); took off {math.dist(took_off.truth[:2], start):.2f} m "
              f"from the home pad")


def case_round_trip_off_pad(uri, sim, pads, start):
    with Link(uri) as link:
        sim_sleep(2.0)
        away = hl_flight(link, (1.0, 0.0), True, "HighLevelCommander")
        t_refused = link.last()[0] / 1000.0
        link.set_param("mission.mode", 0)
        text = write_start(link)
        lines = [ln for ln in text.splitlines() if "mission.start refused" in ln]
        want = "home pad" if not WRONG else "started"
        check("round-trip-off-pad: refusal console line", bool(lines) and want in lines[0],
              f"{lines[:1]!r}")
        value = link.read_param("mission.start")
        check("round-trip-off-pad: mission.start reads 0", value is not None and int(value) == 0,
              f"reads {value}")
        check("round-trip-off-pad: state stays 0", set(link.states()) == {0}, f"states {sorted(set(link.states()))}")
        started = sim.wait_event("state   1", after_s=t_refused - 1.0, timeout_s=1.0)
        check("round-trip-off-pad: no mission ran", started is None, f"{started}")
        print(f"     refused {math.dist(away[:2], start):.2f} m from the home pad; flying back", flush=True)
        hl_flight(link, start, False, "HighLevelCommander back home")
        t_start = link.last()[0] / 1000.0
        write_start(link)
        final = link.wait_final(200.0 / SPEED + 30.0)
        want = 202 if WRONG else 100
        check("round-trip-off-pad: final state after flying home", final == want, f"final {final}, expected {want}")
    end = sim.wait_event("state 100", after_s=t_start) or sim.wait_event("state 2", after_s=t_start)
    home = pads[1] if WRONG else pads[0]
    if check("round-trip-off-pad: truth line", end is not None, f"{end}"):
        check("round-trip-off-pad: truly on the home pad", on_pad(end.truth, home), f"{end}, pad {home}")


def main():
    global WRONG, SPEED
    ap = argparse.ArgumentParser()
    ap.add_argument("--sim", required=True, help="the cfnav binary (release build)")
    ap.add_argument("--port", type=int, default=19857)
    ap.add_argument("--speed", type=float, default=2.0)
    ap.add_argument("--out", default="target/e2e-sequence")
    ap.add_argument("--timeout", type=float, default=300.0, help="wall-clock bound for everything, s")
    ap.add_argument("--expect-wrong", action="store_true")
    ap.add_argument("cases", nargs="*", default=CASES)
    args = ap.parse_args()
    WRONG = args.expect_wrong
    SPEED = args.speed
    for c in args.cases:
        if c not in CASES:
            ap.error(f"unknown case {c}: {CASES}")
    t = threading.Timer(args.timeout, lambda: (print("FAIL: timeout", flush=True), os._exit(1)))
    t.daemon = True
    t.start()
    os.makedirs(args.out, exist_ok=True)
    cflib.crtp.init_drivers()
    pads, start = world_pads(WORLD)
    runs = {"hover-after-flights": case_hover_after_flights, "round-trip-off-pad": case_round_trip_off_pad}
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
    print("missions started after other flights: every check passed", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
