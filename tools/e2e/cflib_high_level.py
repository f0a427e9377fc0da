#!/usr/bin/env python3
"""End-to-end: fly cflib's HighLevelCommander against `cfnav sim --serve` and check the simulator's estimate.

Start the simulator first:   cargo run --release -p cfnav-tools -- sim --serve --port 19852 --speed 1
Then:                        python3 tools/e2e/cflib_high_level.py --uri udp://127.0.0.1:19852

Steps: connect (SyncCrazyflie), log stateEstimate.x/y/z at 10 Hz, take off to 0.5 m in 2 s (yaw=None: the
current heading), go_to +0.5 m in x (relative, smooth) in 2.5 s, go_to back (absolute, linear) in 2.5 s, land
in 2 s, stop. After each step the logged estimate must be within 10 cm of the target (z after landing below
0.15 m). Exit 0 iff every check passes. Uses only port 8 and logging: no parameter cflib's MotionCommander
classes write (kalman.resetEstimation, stabilizer.controller), which cfnav does not declare yet.
"""

import argparse
import os
import sys
import threading
import time

import cflib.crtp
from cflib.crazyflie import Crazyflie
from cflib.crazyflie.log import LogConfig
from cflib.crazyflie.syncCrazyflie import SyncCrazyflie


def say(msg):
    print(msg, flush=True)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('--uri', default='udp://127.0.0.1:19852')
    ap.add_argument('--timeout', type=float, default=90.0)
    args = ap.parse_args()
    t = threading.Timer(args.timeout, lambda: (say('FAIL: timeout'), os._exit(1)))
    t.daemon = True
    t.start()
    cflib.crtp.init_drivers()
    pos = {}
    failures = []
    with SyncCrazyflie(args.uri, cf=Crazyflie(rw_cache=None)) as scf:
        cf = scf.cf
        conf = LogConfig(name='pos', period_in_ms=100)
        for v in ('stateEstimate.x', 'stateEstimate.y', 'stateEstimate.z'):
            conf.add_variable(v, 'float')
        conf.data_received_cb.add_callback(lambda ts, data, lc: pos.update(data))
        cf.log.add_config(conf)
        conf.start()
        time.sleep(2.0)
        x0, y0 = pos['stateEstimate.x'], pos['stateEstimate.y']
        say(f'start ({x0:.2f}, {y0:.2f}, {pos["stateEstimate.z"]:.2f})')
        hl = cf.high_level_commander

        def check(name, x, y, z, tol=0.10):
            p = (pos['stateEstimate.x'], pos['stateEstimate.y'], pos['stateEstimate.z'])
            err = max(abs(p[0] - x), abs(p[1] - y), abs(p[2] - z))
            ok = err <= tol
            say(f'{"ok  " if ok else "FAIL"} {name}: estimate ({p[0]:.2f}, {p[1]:.2f}, {p[2]:.2f}), '
                f'target ({x:.2f}, {y:.2f}, {z:.2f}), off {err:.3f} m')
            if not ok:
                failures.append(name)

        hl.takeoff(0.5, 2.0, yaw=None)
        time.sleep(3.5)
        check('takeoff', x0, y0, 0.5)
        hl.go_to(0.5, 0.0, 0.0, 0.0, 2.5, relative=True)
        time.sleep(4.0)
        check('go_to relative smooth', x0 + 0.5, y0, 0.5)
        hl.go_to(x0, y0, 0.5, 0.0, 2.5, relative=False, linear=True)
        time.sleep(4.0)
        check('go_to absolute linear', x0, y0, 0.5)
        hl.land(0.0, 2.0)
        time.sleep(4.0)
        check('land', x0, y0, 0.0, tol=0.15)
        hl.stop()
        time.sleep(0.5)
        conf.stop()
    if failures:
        say(f'FAIL: {failures}')
        return 1
    say('high-level commander: every target reached')
    return 0


if __name__ == '__main__':
    sys.exit(main())
