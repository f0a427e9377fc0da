#!/usr/bin/env python3
"""End-to-end: cflib's MotionCommander and PositionHlCommander (default and controller=PID) against
`cfnav sim --serve`, judged on the logged stateEstimate.

Start the simulator first (real time: the commanders pace themselves with sleeps):
    cargo run --release -p cfnav-tools -- sim --serve --port 19854 --speed 1
Then:
    python3 tools/e2e/cflib_motion.py --uri udp://127.0.0.1:19854

Steps (default world: the drone stands on the home pad at mission.startX/Y = (0.6, 1.3), nothing within 1 m):
1. MotionCommander(default_height=0.5): take_off (its kalman.resetEstimation first: the estimate goes back to
   the start), forward 0.5 m, turn_left 90 deg, forward 0.3 m (now along +y: the turn was real), land (its
   stop setpoint at the end). MotionCommander dead-reckons (velocity x time), so each move is judged from
   where the previous one ended, along the heading: within 10 cm and 12 deg (one of its 200 ms packet intervals at 60 deg/s), height within 10 cm.
2. PositionHlCommander (default controller, the high-level commander of port 8) starting where the first
   flight landed: take_off to 0.5 m, go_to a point 0.4 m away, land.
3. PositionHlCommander(controller=CONTROLLER_PID) (writes stabilizer.controller = 1): the same back.
After each landing the estimated height must be below 0.15 m and the supervisor must report not flying
(supervisor.info bit 4) within 3 s. The simulator exposes no truth over CRTP: the estimate is judged (its
error against the truth is covered by the simulator's own tests). Exit 0 iff every check passes.
"""

import argparse
import math
import os
import sys
import threading
import time

import cflib.crtp
from cflib.crazyflie import Crazyflie
from cflib.crazyflie.log import LogConfig
from cflib.crazyflie.syncCrazyflie import SyncCrazyflie
from cflib.positioning.motion_commander import MotionCommander
from cflib.positioning.position_hl_commander import PositionHlCommander

TOL_M = 0.10
TOL_YAW_DEG = 12.0  # one 200 ms MotionCommander packet interval at 60 deg/s
IS_FLYING = 0x0010  # supervisor.info bit 4 (stock supervisor.h, cfclient's FlightTab)


def say(msg):
    print(msg, flush=True)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('--uri', default='udp://127.0.0.1:19854')
    ap.add_argument('--timeout', type=float, default=150.0)
    args = ap.parse_args()
    t = threading.Timer(args.timeout, lambda: (say('FAIL: timeout'), os._exit(1)))
    t.daemon = True
    t.start()
    cflib.crtp.init_drivers()
    s = {}
    failures = []

    def pose():
        return (s['stateEstimate.x'], s['stateEstimate.y'], s['stateEstimate.z'], s['stateEstimate.yaw'])

    def check(name, x=None, y=None, z=None, yaw=None, tol=TOL_M):
        p = pose()
        errs = []
        for got, want in ((p[0], x), (p[1], y), (p[2], z)):
            if want is not None:
                errs.append(abs(got - want))
        err = max(errs) if errs else 0.0
        ok = err <= tol
        yaw_err = None
        if yaw is not None:
            yaw_err = abs((p[3] - yaw + 180.0) % 360.0 - 180.0)
            ok = ok and yaw_err <= TOL_YAW_DEG
        want = tuple('-' if v is None else f'{v:.2f}' for v in (x, y, z, yaw))
        say(f'{"ok  " if ok else "FAIL"} {name}: estimate ({p[0]:.2f}, {p[1]:.2f}, {p[2]:.2f}, yaw {p[3]:.0f}), '
            f'target ({", ".join(want)}), off {err:.3f} m' + ('' if yaw_err is None else f', {yaw_err:.1f} deg'))
        if not ok:
            failures.append(name)

    def landed(name):
        deadline = time.time() + 3.0
        while time.time() < deadline and (s['supervisor.info'] & IS_FLYING or s['stateEstimate.z'] > 0.15):
            time.sleep(0.1)
        ok = not (s['supervisor.info'] & IS_FLYING) and s['stateEstimate.z'] <= 0.15
        say(f'{"ok  " if ok else "FAIL"} {name}: z {s["stateEstimate.z"]:.2f} m, '
            f'supervisor.info {s["supervisor.info"]:#06x} (flying bit {"set" if s["supervisor.info"] & IS_FLYING else "clear"})')
        if not ok:
            failures.append(name)

    with SyncCrazyflie(args.uri, cf=Crazyflie(rw_cache=None)) as scf:
        cf = scf.cf
        conf = LogConfig(name='pose', period_in_ms=100)
        for v in ('stateEstimate.x', 'stateEstimate.y', 'stateEstimate.z', 'stateEstimate.yaw'):
            conf.add_variable(v, 'float')
        conf.add_variable('supervisor.info', 'uint16_t')
        conf.data_received_cb.add_callback(lambda ts, data, lc: s.update(data))
        cf.log.add_config(conf)
        conf.start()
        time.sleep(2.0)
        x0 = float(cf.param.get_value('mission.startX'))
        y0 = float(cf.param.get_value('mission.startY'))
        say(f'start: mission.startX/Y ({x0:.2f}, {y0:.2f}), estimate {tuple(round(v, 2) for v in pose())}')

        # 1. MotionCommander.
        mc = MotionCommander(scf, default_height=0.5)
        mc.take_off(0.5, 0.3)
        time.sleep(1.0)
        check('MotionCommander take_off', x0, y0, 0.5)
        # MotionCommander dead-reckons (velocity x time): each move is judged from where the last one ended,
        # along the heading the drone has.
        def move(name, dist, fn):
            bx, by, _, byaw = pose()
            fn()
            time.sleep(1.0)
            h = math.radians(byaw)
            check(name, bx + dist * math.cos(h), by + dist * math.sin(h), 0.5)

        move('MotionCommander forward 0.5 m', 0.5, lambda: mc.forward(0.5, 0.25))
        bx, by = s['stateEstimate.x'], s['stateEstimate.y']
        mc.turn_left(90, 60)
        time.sleep(0.5)
        check('MotionCommander turn_left 90', bx, by, 0.5, yaw=90.0)
        move('MotionCommander forward 0.3 m after the turn', 0.3, lambda: mc.forward(0.3, 0.25))
        mc.land(0.3)
        landed('MotionCommander land')
        time.sleep(1.0)

        # 2. PositionHlCommander, default controller, from where it landed.
        for label, controller in (('PositionHlCommander', None),
                                  ('PositionHlCommander(PID)', PositionHlCommander.CONTROLLER_PID)):
            x1, y1 = s['stateEstimate.x'], s['stateEstimate.y']
            kwargs = {} if controller is None else {'controller': controller}
            pc = PositionHlCommander(scf, x=x1, y=y1, z=0.0, default_velocity=0.3, default_height=0.5, **kwargs)
            if controller == PositionHlCommander.CONTROLLER_PID:
                time.sleep(0.3)  # its parameter write is asynchronous
                got = cf.param.get_value('stabilizer.controller')
                ok = got == '1'
                say(f'{"ok  " if ok else "FAIL"} {label}: stabilizer.controller = {got}')
                if not ok:
                    failures.append(f'{label} controller')
            pc.take_off()
            time.sleep(1.0)
            check(f'{label} take_off', x1, y1, 0.5)
            # Away from the first landing spot and back towards the start, staying off the home pad's rim.
            tx, ty = (x1 - 0.4, y1) if label == 'PositionHlCommander' else (x1 + 0.4, y1)
            pc.go_to(tx, ty, 0.5)
            time.sleep(1.5)
            check(f'{label} go_to ({tx:.2f}, {ty:.2f}, 0.50)', tx, ty, 0.5)
            pc.land()
            landed(f'{label} land')
            time.sleep(1.0)
        conf.stop()
    if failures:
        say(f'FAIL: {failures}')
        return 1
    say('MotionCommander and PositionHlCommander (default, PID): every target reached, landed')
    return 0


if __name__ == '__main__':
    sys.exit(main())
