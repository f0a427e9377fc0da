#!/usr/bin/env python3
"""Persistent parameters end to end: unmodified cflib (PyPI) against `cfnav sim --serve --param-store FILE`,
with the simulator restarted in between, as a drone is power-cycled.

The calls are cflib's `Param.persistent_store`, `persistent_get_state` and `persistent_clear`, the ones
cfclient's "Persistent Parameter Management" panel makes. Checks, each printed as it passes, exit 1 on the
first failure:
1. the tuning parameters are marked persistent (extended type), `mission.goalX` is not;
2. boot 1 (blank store): set a float, a uint16 and a uint8 tuning parameter, `persistent_store` each;
   `persistent_get_state` says stored, with the power-on default and the stored value;
3. boot 2: the three values are in effect again and still stored; `persistent_clear` one, which then reads
   "not stored" (its value stays in effect until the next boot, as stock);
4. boot 3: the cleared one is back at its default, the other two still carry their stored values; clear them.

Usage: cflib_persistent.py --sim PATH/TO/cfnav [--port 19853] [--store FILE]
"""

import argparse
import os
import sys
import tempfile
import threading
import time

import cflib.crtp
from cflib.crazyflie import Crazyflie
from cflib.crazyflie.syncCrazyflie import SyncCrazyflie

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from sim_truth import Sim  # noqa: E402

# (name, value written, power-on default): a float, a uint16 and a uint8.
PARAMS = [("pid_rate.roll_kp", 180.0, 250.0), ("posCtlPid.thrustBase", 40000, None), ("avoid.mode", 1, 0)]
TIMEOUT_S = 10.0


def fail(text):
    print(f"FAIL: {text}", flush=True)
    sys.exit(1)


def ok(text):
    print(f"ok: {text}", flush=True)


def power_on(binary, port, store, log_path):
    """`cfnav sim --serve` with the store file, started and stopped like a power cycle (sim_truth.Sim)."""
    return Sim(binary, port, None, log_path, extra=["--param-store", store], append=True)


def call(fn, name):
    """Runs a cflib persistent call with a callback; returns the callback's second argument."""
    got = []
    done = threading.Event()

    def cb(complete_name, result):
        if complete_name == name:
            got.append(result)
            done.set()

    fn(name, cb)
    if not done.wait(TIMEOUT_S):
        fail(f"{fn.__name__}({name}) got no answer in {TIMEOUT_S} s")
    return got[0]


def set_and_wait(cf, name, value):
    """Writes a value and waits for the echo (cflib's update callback)."""
    group, short = name.split(".")
    done = threading.Event()
    seen = []

    def cb(complete_name, v):
        seen.append(v)
        done.set()

    cf.param.add_update_callback(group=group, name=short, cb=cb)
    cf.param.set_value(name, str(value))
    if not done.wait(TIMEOUT_S):
        fail(f"no echo for {name} = {value}")
    cf.param.remove_update_callback(group=group, name=short, cb=cb)
    if float(seen[-1]) != float(value):
        fail(f"{name} = {value} echoed {seen[-1]}")


def value(cf, name):
    return float(cf.param.get_value(name))


def connect(uri):
    scf = SyncCrazyflie(uri, cf=Crazyflie(rw_cache=None))
    scf.open_link()
    # cflib fetches the extended types (persistence) after the TOC: wait until the parameters are updated.
    scf.wait_for_params()
    return scf


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sim", required=True, help="the cfnav binary")
    ap.add_argument("--port", type=int, default=19853)
    ap.add_argument("--store", help="EEPROM file (default: a fresh temporary file)")
    args = ap.parse_args()
    tmp = tempfile.TemporaryDirectory()
    store = args.store or os.path.join(tmp.name, "eeprom.bin")
    if os.path.exists(store):
        os.remove(store)
    uri = f"udp://127.0.0.1:{args.port}"
    log = os.path.join(tmp.name, "serve.log")
    cflib.crtp.init_drivers()
    defaults = {}

    try:
        # Boot 1: a blank store.
        with power_on(args.sim, args.port, store, log):
            scf = connect(uri)
            cf = scf.cf
            for name, _, _ in PARAMS:
                if not cf.param.toc.get_element_by_complete_name(name).is_persistent():
                    fail(f"{name} is not marked persistent")
            if cf.param.toc.get_element_by_complete_name("mission.goalX").is_persistent():
                fail("mission.goalX is marked persistent")
            ok("tuning parameters are persistent, mission.goalX is not")
            for name, written, default in PARAMS:
                defaults[name] = value(cf, name)
                if default is not None and defaults[name] != default:
                    fail(f"{name} powers on at {defaults[name]}, expected {default}")
                state = call(cf.param.persistent_get_state, name)
                if state is None or state.is_stored:
                    fail(f"{name} on a blank store: {state}")
                set_and_wait(cf, name, written)
                if not call(cf.param.persistent_store, name):
                    fail(f"persistent_store({name}) failed")
                state = call(cf.param.persistent_get_state, name)
                if not (state.is_stored and float(state.default_value) == defaults[name]
                        and float(state.stored_value) == float(written)):
                    fail(f"{name} after persistent_store: {state}")
                ok(f"{name} = {written} stored (default {defaults[name]})")
            scf.close_link()
        if not os.path.exists(store) or os.path.getsize(store) != 8192:
            fail(f"{store} is not an 8 KB EEPROM image")

        # Boot 2: the values are back; clear the first.
        with power_on(args.sim, args.port, store, log):
            scf = connect(uri)
            cf = scf.cf
            for name, written, _ in PARAMS:
                if value(cf, name) != float(written):
                    fail(f"after a restart {name} = {value(cf, name)}, stored {written}")
                state = call(cf.param.persistent_get_state, name)
                if not (state.is_stored and float(state.stored_value) == float(written)):
                    fail(f"after a restart {name}: {state}")
            ok("after a restart every stored value is in effect and still stored")
            cleared = PARAMS[0][0]
            if not call(cf.param.persistent_clear, cleared):
                fail(f"persistent_clear({cleared}) failed")
            state = call(cf.param.persistent_get_state, cleared)
            if state.is_stored or float(state.default_value) != defaults[cleared]:
                fail(f"{cleared} after persistent_clear: {state}")
            ok(f"{cleared} cleared: not stored, default {state.default_value}")
            scf.close_link()

        # Boot 3: the cleared one is at its default, the others still stored.
        with power_on(args.sim, args.port, store, log):
            scf = connect(uri)
            cf = scf.cf
            if value(cf, cleared) != defaults[cleared]:
                fail(f"{cleared} = {value(cf, cleared)} after clear and restart, default {defaults[cleared]}")
            for name, written, _ in PARAMS[1:]:
                if value(cf, name) != float(written):
                    fail(f"after the second restart {name} = {value(cf, name)}, stored {written}")
                if not call(cf.param.persistent_clear, name):
                    fail(f"persistent_clear({name}) failed")
            ok(f"after another restart {cleared} is at its default, the others kept their values; cleared")
            scf.close_link()
    finally:
        tmp.cleanup()
    print("persistent parameters over cflib: all checks passed", flush=True)


if __name__ == "__main__":
    main()
