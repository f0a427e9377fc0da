#!/usr/bin/env python3
"""cflib without the GUI against `cfnav sim --serve`: the stock names cfclient and cflib's own classes use.

Unmodified cflib (PyPI) checks, each printed as it passes, exit 1 on the first failure:
1. every `deck.*` name the stock cfclient reads is in the parameter TOC, read-only; bcFlow2 and
   bcMultiranger read 1 (the simulated drone carries both), the others 0;
2. cfclient's log blocks (battery, motors, pose; the Plotter's shipped configurations when cfclient is
   installed) are accepted and stream values; the battery level and state match the voltage;
3. `PositionHlCommander(controller=CONTROLLER_PID)` (writes `stabilizer.controller`) constructs without
   raising, and the value reads back 1;
4. `MotionCommander`'s estimator reset (`kalman.resetEstimation` 1 then 0, what `take_off` runs first) does
   not raise and re-anchors the estimate at `mission.startX/startY`: moved to (1.0, 1.0) first, the logged
   `stateEstimate.x/y` follow.
"""

import argparse
import glob
import json
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

DECKS = ["bcFlow", "bcFlow2", "bcZRanger", "bcZRanger2", "bcMultiranger", "bcLighthouse4", "bcLoco",
         "bcDWM1000", "bcLedRing", "bcColorLedBot", "bcColorLedTop"]

# cfclient 2026.8.1: ui/main.py (Battery), ui/tabs/FlightTab.py (Motors), ui/pose_logger.py (Pose).
CFCLIENT_BLOCKS = {
    "Battery": [("pm.vbat", "float"), ("pm.state", "int8_t")],
    "Motors": [("stabilizer.thrust", "uint16_t"), ("motor.m1", None), ("motor.m2", None), ("motor.m3", None),
               ("motor.m4", None), ("sys.canfly", None), ("supervisor.info", None)],
    "Pose": [(f"stateEstimate.{v}", "float") for v in ("x", "y", "z", "roll", "pitch", "yaw")],
}


def fail(text):
    print(f"FAIL: {text}", flush=True)
    sys.exit(1)


def plotter_blocks():
    """The Plotter's shipped log configurations, if cfclient is installed."""
    try:
        import cfclient
    except ImportError:
        return {}
    out = {}
    for path in glob.glob(os.path.join(cfclient.module_path, "configs", "log", "**", "*.json"), recursive=True):
        block = json.load(open(path))["logconfig"]["logblock"]
        out[f"Plotter {block['name']}"] = [(v["name"], v["fetch_as"]) for v in block["variables"]]
    return out


def sample(cf, name, variables, period_ms=50, seconds=0.6):
    """Starts a block as cfclient does; returns its last sample."""
    conf = LogConfig(name, period_ms)
    for var, fetch in variables:
        if fetch:
            conf.add_variable(var, fetch)
        else:
            conf.add_variable(var)
    got = []
    done = threading.Event()

    def on_data(ts, data, c):
        got.append(data)
        if len(got) >= 3:
            done.set()

    try:
        cf.log.add_config(conf)
    except (KeyError, AttributeError) as e:
        fail(f"cflib refuses cfclient's {name} block: {e}")
    conf.data_received_cb.add_callback(on_data)
    conf.start()
    done.wait(seconds + 2.0)
    conf.stop()
    conf.delete()
    if not got:
        fail(f"no data for the {name} block")
    return got[-1]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--uri", default="udp://127.0.0.1:19850")
    args = ap.parse_args()
    cflib.crtp.init_drivers()
    with SyncCrazyflie(args.uri, cf=Crazyflie(rw_cache=None)) as scf:
        cf = scf.cf
        end = time.monotonic() + 10
        while not cf.param.is_updated and time.monotonic() < end:
            time.sleep(0.05)
        if not cf.param.is_updated:
            fail("parameters not all read within 10 s")

        # 1. Decks.
        for deck in DECKS:
            el = cf.param.toc.get_element_by_complete_name(f"deck.{deck}")
            if el is None:
                fail(f"deck.{deck} is not in the parameter TOC")
            if el.get_readable_access() != "RO" or el.ctype != "uint8_t":
                fail(f"deck.{deck}: {el.ctype} {el.get_readable_access()}, stock is uint8_t RO")
            want = "1" if deck in ("bcFlow2", "bcMultiranger") else "0"
            if cf.param.get_value(f"deck.{deck}") != want:
                fail(f"deck.{deck} = {cf.param.get_value(f'deck.{deck}')}, expected {want}")
        print(f"decks: {len(DECKS)} names, bcFlow2 = bcMultiranger = 1, the others 0", flush=True)

        # 2. cfclient's log blocks.
        blocks = dict(CFCLIENT_BLOCKS)
        blocks.update(plotter_blocks())
        for name, variables in blocks.items():
            data = sample(cf, name, variables)
            print(f"log block {name}: {data}", flush=True)
        level = sample(cf, "level", [("pm.vbat", "float"), ("pm.batteryLevel", None), ("pm.state", None)])
        curve = [3.00, 3.78, 3.83, 3.87, 3.89, 3.92, 3.96, 4.00, 4.04, 4.10]  # stock pm_stm32f4.c
        v = level["pm.vbat"]
        want = 0 if v < curve[0] else 10 * next((i for i, c in enumerate(curve) if v <= c), 9)
        if abs(level["pm.batteryLevel"] - want) > 10 or level["pm.state"] not in (0, 3):
            fail(f"battery {level}: level {want} % expected")

        # 3. PositionHlCommander(controller=PID).
        try:
            PositionHlCommander(scf, controller=PositionHlCommander.CONTROLLER_PID)
        except Exception as e:  # noqa: BLE001 (any exception is the failure reported)
            fail(f"PositionHlCommander(controller=PID) raised {e!r}")
        time.sleep(0.3)
        if cf.param.get_value("stabilizer.controller") != "1":
            fail(f"stabilizer.controller = {cf.param.get_value('stabilizer.controller')}, expected 1")
        print("PositionHlCommander(controller=PID): stabilizer.controller = 1", flush=True)

        # 4. MotionCommander's estimator reset re-anchors the estimate at the start position.
        cf.param.set_value("mission.startX", "1.0")
        cf.param.set_value("mission.startY", "1.0")
        time.sleep(0.3)
        try:
            MotionCommander(scf)._reset_position_estimator()
        except Exception as e:  # noqa: BLE001
            fail(f"MotionCommander's kalman.resetEstimation writes raised {e!r}")
        pose = sample(cf, "pose", [("stateEstimate.x", "float"), ("stateEstimate.y", "float")])
        if abs(pose["stateEstimate.x"] - 1.0) > 0.05 or abs(pose["stateEstimate.y"] - 1.0) > 0.05:
            fail(f"after kalman.resetEstimation the estimate is {pose}, expected (1.0, 1.0)")
        if cf.param.get_value("kalman.resetEstimation") != "0":
            fail("kalman.resetEstimation does not read 0 after the reset")
        print(f"MotionCommander reset: estimate re-anchored at ({pose['stateEstimate.x']:.3f}, "
              f"{pose['stateEstimate.y']:.3f})", flush=True)
    print("cflib stock names: passed", flush=True)


if __name__ == "__main__":
    main()
