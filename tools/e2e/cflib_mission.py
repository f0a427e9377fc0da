#!/usr/bin/env python3
"""End-to-end: fly the simulator's mission with unmodified cflib (>= 0.1.32) over UDP.

Start the simulator first:   cargo run --release -p cfnav-tools -- sim --serve --port 19850 --speed 20
Then:                        python3 tools/e2e/cflib_mission.py [--uri udp://127.0.0.1:19850] [--goal X,Y]

Steps (docs/radio.md): connect with SyncCrazyflie and wait until fully connected, list the TOCs, set
mission.goalX/goalY (the values the simulator reports, i.e. the world's, unless --goal is given), check that an
out-of-arena goalX is refused (the value read back is unchanged), log mission.state and stateEstimate.x/y/z at
10 Hz, write mission.start = 1 and wait for mission.state >= 100. Exit status 0 iff mission.state == 100.
"""

import argparse
import importlib.metadata
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


def watchdog(seconds):
    """Ends the process if the whole test takes longer than `seconds` (cflib has no timeouts over UDP)."""

    def fire():
        say(f'FAIL: no result after {seconds:.0f} s wall')
        os._exit(1)

    t = threading.Timer(seconds, fire)
    t.daemon = True
    t.start()


def _await_update(cf, name, send, what, timeout):
    """Registers for `name`'s next update, calls `send()`, and returns the value that update carried (a
    string); raises `what` if none comes within `timeout` seconds."""
    group, var = name.split('.')
    got = {}
    done = threading.Event()

    def cb(n, v):
        got['v'] = v
        done.set()

    cf.param.add_update_callback(group=group, name=var, cb=cb)
    try:
        send()
        if not done.wait(timeout):
            raise RuntimeError(f'{what} within {timeout} s')
    finally:
        cf.param.remove_update_callback(group=group, name=var, cb=cb)
    return got['v']


def set_and_wait(cf, name, value, timeout=5.0):
    """Writes `name` and waits for the firmware's echo; returns the value the echo carried (a string)."""
    return _await_update(cf, name, lambda: cf.param.set_value(name, value),
                         f'no echo for {name} := {value}', timeout)


def reread(cf, name, timeout=5.0):
    """Asks the firmware for the current value of `name` and returns it (a string)."""
    return _await_update(cf, name, lambda: cf.param.request_param_update(name),
                         f'no reply reading {name}', timeout)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--uri', default='udp://127.0.0.1:19850')
    ap.add_argument('--goal', help='X,Y in metres (default: the goal the simulator reports)')
    ap.add_argument('--timeout', type=float, default=120.0, help='wall seconds for the whole test')
    args = ap.parse_args()

    watchdog(args.timeout)
    t0 = time.monotonic()
    try:
        version = importlib.metadata.version('cflib')
    except importlib.metadata.PackageNotFoundError:
        version = '?'
    say(f'cflib {version}, connecting to {args.uri}')
    cflib.crtp.init_drivers()
    cf = Crazyflie(rw_cache=None)
    console = {'buf': ''}

    def on_console(text):
        # The firmware sends console text in ≤ 30-byte packets: print whole lines.
        console['buf'] += text
        while '\n' in console['buf']:
            line, console['buf'] = console['buf'].split('\n', 1)
            say(f'  [console] {line}')

    cf.console.receivedChar.add_callback(on_console)

    with SyncCrazyflie(args.uri, cf=cf) as scf:
        say(f'connected after {time.monotonic() - t0:.2f} s, protocol {cf.platform.get_protocol_version()}')
        scf.wait_for_params()
        say(f'fully connected after {time.monotonic() - t0:.2f} s')

        params = sorted(f'{g}.{n}' for g, names in cf.param.toc.toc.items() for n in names)
        logs = sorted(f'{g}.{n}' for g, names in cf.log.toc.toc.items() for n in names)
        say(f'param TOC ({len(params)}): {", ".join(params)}')
        say(f'log TOC ({len(logs)}): {", ".join(logs)}')
        for needed in ('mission.start', 'mission.goalX', 'mission.goalY'):
            if needed not in params:
                say(f'FAIL: {needed} is not in the param TOC')
                return 1
        for needed in ('mission.state', 'stateEstimate.x', 'stateEstimate.y', 'stateEstimate.z'):
            if needed not in logs:
                say(f'FAIL: {needed} is not in the log TOC')
                return 1

        if args.goal:
            gx, gy = (float(v) for v in args.goal.split(','))
        else:
            gx = float(cf.param.get_value('mission.goalX'))
            gy = float(cf.param.get_value('mission.goalY'))
        ex = float(set_and_wait(cf, 'mission.goalX', gx))
        ey = float(set_and_wait(cf, 'mission.goalY', gy))
        say(f'goal set: ({ex:.2f}, {ey:.2f})')
        if abs(ex - gx) > 1e-4 or abs(ey - gy) > 1e-4:
            say(f'FAIL: goal echo ({ex}, {ey}) differs from ({gx}, {gy})')
            return 1

        echo = float(set_and_wait(cf, 'mission.goalX', 99.0))
        back = float(reread(cf, 'mission.goalX'))
        say(f'goalX := 99.0 -> echo {echo:.2f}, read back {back:.2f}')
        if abs(back - gx) > 1e-4 or abs(echo - gx) > 1e-4:
            say('FAIL: an out-of-arena goalX was not refused')
            return 1
        say('out-of-arena goalX refused, value unchanged')

        samples = []
        first_final = threading.Event()
        start_back_to_zero = threading.Event()
        last = {'state': None}
        # A final state counts only once the mission has been seen running after our start (a drone that
        # already completed a mission reports 100 until it starts again).
        phase = {'armed': False, 'running': False}

        def on_log(ts, data, conf):
            s = int(data['mission.state'])
            x, y, z = data['stateEstimate.x'], data['stateEstimate.y'], data['stateEstimate.z']
            samples.append((ts, s, x, y, z))
            if s != last['state'] or len(samples) % 100 == 0:
                mark = '*' if s != last['state'] else ' '
                say(f'  {mark} t={ts / 1000:7.2f} s  state {s:3d}  estimate ({x:5.2f}, {y:5.2f}, {z:5.2f})')
                last['state'] = s
            if phase['armed'] and s < 100:
                phase['running'] = True
            if phase['running'] and s >= 100:
                first_final.set()

        conf = LogConfig(name='mission', period_in_ms=100)
        for name in ('mission.state', 'stateEstimate.x', 'stateEstimate.y', 'stateEstimate.z'):
            conf.add_variable(name)
        cf.log.add_config(conf)
        conf.data_received_cb.add_callback(on_log)
        conf.start()

        cf.param.add_update_callback(
            group='mission', name='start', cb=lambda n, v: start_back_to_zero.set() if int(v) == 0 else None
        )
        phase['armed'] = True
        echo = int(set_and_wait(cf, 'mission.start', 1))
        say(f'mission.start := 1 -> echo {echo}')
        if echo != 1:
            say('FAIL: the start was refused')
            return 1

        remaining = args.timeout - (time.monotonic() - t0) - 2.0
        if not first_final.wait(max(remaining, 1.0)):
            say(f'FAIL: mission.state did not reach 100 within the timeout ({len(samples)} samples)')
            return 1
        final = next(s for _, s, *_ in reversed(samples) if s >= 100)
        reset_seen = start_back_to_zero.wait(3.0)
        conf.stop()
        conf.delete()
        say(
            f'mission ended: state {final} after {samples[-1][0] / 1000:.1f} s simulated, '
            f'{time.monotonic() - t0:.1f} s wall, {len(samples)} log samples; '
            f'mission.start back to 0: {"yes" if reset_seen else "no"}'
        )
        if final != 100:
            say(f'FAIL: mission ended with state {final}, not 100 (completed)')
            return 1
        if not reset_seen:
            say('FAIL: mission.start was not set back to 0 (no VALUE_UPDATED)')
            return 1
    say('PASS')
    return 0


if __name__ == '__main__':
    sys.exit(main())
