#!/usr/bin/env python3
"""The stock cfclient (PyPI `cfclient`, unmodified) against `cfnav sim --serve`, driven as a user would.

Starts cfclient's own main window in this process (what its `cfclient` entry point does) with a fresh
configuration directory, under whatever X display is set (CI runs it under `xvfb-run`), then:

1. waits for cfclient's start-up scan to list the URI (the simulator must listen on 19850-19859, the ports
   cflib's UDP scan probes), selects it and clicks Connect;
2. opens every tab of the Tabs menu;
3. waits until every parameter of the Parameters tab shows a value and checks them against cflib's own
   parameter cache;
4. edits `mission.goalX` in the Parameters tab (select it, type a value, click Set) and waits until the
   tab shows the value the drone echoed; a second, refused edit (`mission.height` = 9) must come back
   with the value in effect;
5. checks the battery display (voltage text and bar) and the Flight tab's state estimate, thrust and motor
   fields, which cfclient fills from its log blocks;
6. checks the Flight tab's Supervisor box: auto-armed on the ground, "Flying" with thrust and motor bars
   after `mission.start = 1`, no longer flying after the abort (`mission.start = 0`);
7. saves screenshots of the Parameters and Flight tabs, on the ground and flying (`--shots DIR`);
8. fails if cfclient raised or logged an exception, logged an error, or refused a log block.

Exit status 0 when every check passed, 1 otherwise (each failed check is printed), 2 on a setup problem.
"""

import argparse
import logging
import os
import sys
import tempfile
import threading
import time
import traceback

PROBLEMS = []


def problem(text):
    PROBLEMS.append(text)
    print(f"FAIL: {text}", flush=True)


class Collector(logging.Handler):
    """Keeps every record cfclient and cflib log; errors, exceptions and refused log blocks are problems."""

    # cflib/cfclient warnings that mean a name is missing or a log block was refused.
    BAD_WARNINGS = ("not in TOC", "not in param TOC", "KeyError", "AttributeError", "too large",
                    "Error when", "not found in TOC", "Unable to find variable")

    def __init__(self):
        super().__init__(level=logging.DEBUG)
        self.lines = []

    def emit(self, record):
        text = record.getMessage()
        line = f"{record.levelname}:{record.name}:{text}"
        self.lines.append(line)
        if record.levelno >= logging.WARNING:
            print(line, flush=True)
        if record.exc_info or record.levelno >= logging.ERROR:
            problem(f"cfclient logged {line}")
        elif record.levelno >= logging.WARNING and any(b in text for b in self.BAD_WARNINGS):
            problem(f"cfclient warned {line}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--uri", default="udp://127.0.0.1:19850")
    ap.add_argument("--timeout", type=float, default=60.0, help="seconds for the whole run")
    ap.add_argument("--shots", default="target/cfclient", help="folder for the screenshots")
    args = ap.parse_args()

    # A fresh configuration: cfclient keeps its config (appdirs) and cflib its TOC cache under these.
    home = tempfile.mkdtemp(prefix="cfclient-home-")
    os.environ["HOME"] = home
    os.environ["XDG_CONFIG_HOME"] = os.path.join(home, ".config")
    os.environ["XDG_CACHE_HOME"] = os.path.join(home, ".cache")
    os.makedirs(args.shots, exist_ok=True)

    collector = Collector()
    logging.basicConfig(level=logging.INFO, handlers=[collector])

    def excepthook(kind, value, tb):
        problem("uncaught exception: " + "".join(traceback.format_exception(kind, value, tb)))

    sys.excepthook = excepthook
    threading.excepthook = lambda a: excepthook(a.exc_type, a.exc_value, a.exc_traceback)

    try:
        import cfclient
        from cfclient.ui.main import MainUI, UIState
        from cfclient.utils.ui import UiUtils
        from PyQt6.QtCore import QTimer
        from PyQt6.QtWidgets import QApplication
    except ImportError as e:
        print(f"cannot import cfclient (pip install cfclient): {e}", file=sys.stderr)
        return 2
    print(f"cfclient {cfclient.VERSION}, config in {cfclient.config_path}", flush=True)

    app = QApplication([sys.argv[0]])
    app.setStyle("Fusion")
    window = MainUI()
    app.setFont(UiUtils.FONT)
    window.resize(1400, 900)
    window.show()
    window.set_default_theme()
    cf = window.cf

    def wait(cond, seconds, what):
        """Runs the Qt event loop until `cond()` is true; a problem after `seconds`."""
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            app.processEvents()
            if cond():
                return True
            time.sleep(0.02)
        problem(f"timed out after {seconds:.0f} s waiting for {what}")
        return False

    def pump(seconds):
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            app.processEvents()
            time.sleep(0.02)

    def shot(name):
        path = os.path.join(args.shots, name)
        window.grab().save(path)
        print(f"screenshot {path}", flush=True)

    # The harness's own pauses: a thread that wakes every 50 ms records the longest gap between wake-ups. A
    # process starved that long (a loaded machine) also stops cflib's pings, and a drone (stock, and cfnav
    # after 3 s) deletes the log blocks of a link that fell silent: the Flight tab then freezes on its last
    # values. The figure is printed, and a failed wait says whether it happened.
    stalls = {"longest_s": 0.0}

    def stall_watch():
        last = time.monotonic()
        while True:
            time.sleep(0.05)
            now = time.monotonic()
            stalls["longest_s"] = max(stalls["longest_s"], now - last)
            last = now

    threading.Thread(target=stall_watch, daemon=True).start()
    # When cflib last delivered log data of any block (cfclient's own blocks, counted from step 5 on).
    log_seen = {"at": None}

    def watch_log_blocks():
        for block in cf.log.log_blocks:
            block.data_received_cb.add_callback(lambda *_: log_seen.__setitem__("at", time.monotonic()))

    def link_report():
        age = "never" if log_seen["at"] is None else f"{time.monotonic() - log_seen['at']:.1f} s ago"
        return (f"log data last received {age}; the harness's longest stall {stalls['longest_s']:.2f} s "
                f"(a silent link loses its log blocks after 3 s)")

    deadline = time.monotonic() + args.timeout
    left = lambda: max(1.0, deadline - time.monotonic())  # noqa: E731

    def run():
        # 1. The start-up scan lists the URI; select it and click Connect.
        combo = window.interfaceCombo

        def listed():
            return combo.findText(args.uri) >= 0

        if not listed():
            window.scanButton.click()
        if not wait(listed, min(20, left()), f"cfclient's scan to list {args.uri}"):
            return
        combo.setCurrentIndex(combo.findText(args.uri))
        t0 = time.monotonic()
        window.connectButton.click()
        if not wait(lambda: window.uiState == UIState.CONNECTED and cf.param.is_updated, min(30, left()),
                    "connected with every parameter read"):
            return
        print(f"connected and every parameter read in {time.monotonic() - t0:.2f} s", flush=True)

        # 2. Every tab of the Tabs menu.
        tabs = window.loaded_tab_toolboxes
        for name, tab in tabs.items():
            if not tab.tab_action_item.isChecked():
                tab.tab_action_item.trigger()
        print(f"tabs open: {', '.join(sorted(tabs))}", flush=True)
        pump(1.0)

        # 3. Every parameter shows a value, the one cflib holds.
        param_tab = tabs["Parameters"]
        model = param_tab._model
        toc = cf.param.toc.toc
        n_toc = sum(len(g) for g in toc.values())

        def shown():
            return {f"{g.name}.{c.name}": c.value for g in model._nodes for c in g.children}

        if not wait(lambda: len(shown()) == n_toc and all(v != "" for v in shown().values()), min(10, left()),
                    "a value for every parameter in the Parameters tab"):
            print(f"shown: {shown()}")
        values = shown()
        empty = [k for k, v in values.items() if v == ""]
        if empty:
            problem(f"parameters without a value in the tab: {empty}")
        from cfclient.ui.tabs.ParamTab import round_if_float
        for name, v in values.items():
            if v != round_if_float(cf.param.get_value(name)):
                problem(f"{name}: tab shows {v}, cflib holds {cf.param.get_value(name)}")
        print(f"Parameters tab: {len(values)} parameters, all with a value", flush=True)

        # 4. An edit through the tab, read back; a refused edit shows the value in effect.
        window.tab_widget.setCurrentWidget(param_tab)

        def edit(name, text):
            group, param = name.split(".")
            proxy = param_tab.proxyModel
            for r in range(proxy.rowCount(param_tab.paramTree.rootIndex())):
                gi = proxy.index(r, 0, param_tab.paramTree.rootIndex())
                if gi.data() != group:
                    continue
                param_tab.paramTree.expand(gi)
                for c in range(proxy.rowCount(gi)):
                    ci = proxy.index(c, 0, gi)
                    if ci.data() == param:
                        param_tab.paramTree.setCurrentIndex(ci)
                        pump(0.2)
                        param_tab.currentValue.setText(text)
                        param_tab.setParamButton.click()
                        return True
            problem(f"{name} not found in the Parameters tab")
            return False

        if edit("mission.goalX", "4.5"):
            wait(lambda: shown()["mission.goalX"] == "4.5" and cf.param.get_value("mission.goalX") == "4.5",
                 min(5, left()), "mission.goalX = 4.5 read back in the tab")
            print(f"edit: mission.goalX 5 -> {shown()['mission.goalX']} (echoed by the drone)", flush=True)
        before = shown()["mission.height"]
        if edit("mission.height", "9"):
            pump(0.5)
            after = shown()["mission.height"]
            if after != before:
                problem(f"refused edit: mission.height shows {after}, expected the value in effect {before}")
            print(f"refused edit: mission.height = 9 -> tab shows {after} (value in effect)", flush=True)
        param_tab.paramTree.scrollToTop()
        pump(0.3)
        shot("cfclient-parameters.png")

        # 5. Battery display and the Flight tab's state estimate, thrust and motors (from log blocks).
        watch_log_blocks()
        flight = tabs["Flight Control"]
        window.tab_widget.setCurrentWidget(flight)
        wait(lambda: window._aff_volts.text() not in ("", "0.000") and flight.estimateZ.text() != "",
             min(10, left()), "battery voltage and state estimate shown")
        volts = window._aff_volts.text()
        try:
            if not 3.0 < float(volts) < 4.5:
                problem(f"battery shows {volts} V")
        except ValueError:
            problem(f"battery shows {volts!r}")
        if window.batteryBar.value() <= 0:
            problem(f"battery bar at {window.batteryBar.value()}")
        est = {w: getattr(flight, w).text() for w in
               ("estimateX", "estimateY", "estimateZ", "estimateRoll", "estimatePitch", "estimateYaw")}
        for w, v in est.items():
            if v == "":
                problem(f"Flight tab {w} is empty")
        x, y = float(est["estimateX"] or "nan"), float(est["estimateY"] or "nan")
        sx, sy = float(cf.param.get_value("mission.startX")), float(cf.param.get_value("mission.startY"))
        if not (abs(x - sx) < 0.3 and abs(y - sy) < 0.3):
            problem(f"Flight tab estimate ({x}, {y}) is not at the start ({sx:.2f}, {sy:.2f})")
        print(f"battery {volts} V (bar {window.batteryBar.value()}), estimate {est}, "
              f"thrust {flight.estimateThrust.text()!r}", flush=True)
        pump(0.5)
        shot("cfclient-flight.png")

        # 6. The Flight tab's Supervisor box (from `supervisor.info`, protocol >= 7) on the ground and in
        # flight: auto-armed on the ground (as a stock Crazyflie 2.1), "Flying" with thrust and motor bars
        # once a mission (mission.start = 1) has taken off; the abort (mission.start = 0) lands it again.
        if not flight._supervisor_state.isVisible():
            problem("Flight tab: the Supervisor box is hidden (protocol version < 7?)")
        if flight.armButton.text() != "Auto armed":
            problem(f"Flight tab: arm button says {flight.armButton.text()!r} on the ground, expected 'Auto armed'")
        cf.param.set_value("mission.start", "1")
        if wait(lambda: flight._supervisor_state.text() == "Flying" and flight.estimateThrust.text() != "0.00%"
                and min(getattr(flight, f"actualM{i}").value() for i in range(1, 5)) > 0,
                min(10, left()), "the Supervisor box to say Flying, with thrust and motors, after mission.start"):
            pump(1.0)
            motors = [getattr(flight, f"actualM{i}").value() for i in range(1, 5)]
            print(f"flying: supervisor {flight._supervisor_state.text()!r}, arm button "
                  f"{flight.armButton.text()!r}, thrust {flight.estimateThrust.text()!r}, motors {motors}, "
                  f"z {flight.estimateZ.text()}", flush=True)
            shot("cfclient-flying.png")
        cf.param.set_value("mission.start", "0")
        if not wait(lambda: flight._supervisor_state.text() != "Flying", min(15, left()), "the abort's landing"):
            print(f"after the abort: {link_report()}", flush=True)
        print(f"after the abort: supervisor {flight._supervisor_state.text()!r}, "
              f"arm button {flight.armButton.text()!r}", flush=True)

    try:
        run()
    finally:
        cf.close_link()
        pump(0.5)
        window.close()
        app.processEvents()

    print(f"harness: longest stall {stalls['longest_s']:.2f} s", flush=True)
    # Every log block cfclient asked for was accepted (cflib marks a refused one `valid = False` or logs).
    if PROBLEMS:
        print(f"cfclient check: {len(PROBLEMS)} problem(s)", flush=True)
        return 1
    print("cfclient check: passed", flush=True)
    return 0


if __name__ == "__main__":
    code = main()
    # Qt and cflib threads: leave at once with the verdict.
    os._exit(code)
