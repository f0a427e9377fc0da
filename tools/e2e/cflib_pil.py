#!/usr/bin/env python3
"""End-to-end: unmodified cflib connects to the *emulated firmware image* (cfnav-pil).

Usage: cflib_pil.py --pil target/debug/cfnav-pil --elf target/thumbv7em-none-eabihf/release/firmware
                    [--port 19860] [--timeout 230] [--samples 5] [--json target/pil/cflib.json]

Starts `cfnav-pil --serve 127.0.0.1:PORT` (the unmodified ELF on rsemu, its syslink's nRF51 end bridged to
UDP with the framing of `cfnav sim --serve`), waits until the bridge answers cflib's scan probe, then with
cflib (no patch, no cache: every TOC entry is read through the emulated syslink):
  1. connects (SyncCrazyflie: platform, log TOC, memories, param TOC) and waits for fully_connected (every
     parameter's value read);
  2. writes mission.startX = 1.25 and reads it back with a fresh param read (request_param_update), which
     must be 1.25 and differ from the value read at connect;
  3. starts a log block (pm.vbat, stateEstimate.z) at 100 ms and receives at least --samples samples; pm.vbat
     must be the 4.0 V the emulated nRF51 reports in its PM_BATTERY_STATE packets (nrf51.rs VBAT_V): the
     battery stream reached the image's power manager and came back through its log service.
Prints what it saw with wall times. Exit 0 iff every step passed; 1 on any failure or the timeout.

cfnav-pil's virtual-time budget (--virtual-seconds, passed as --serve-seconds) starts at cflib's first request,
not at boot, so cflib's wall-clock pacing cannot race it; the wall-clock limit is --timeout.

--reduced (a shorter connect, kept for bisecting an emulator fault such as the loss of ITSTATE on
exception entry that once crashed the image under the full connect, docs/pil.md): cflib's own UdpDriver, unmodified,
asks the link source, the protocol version, the log and param TOC infos, walks the param TOC to
mission.startX, writes 1.25 and reads it back; cfnav-pil then runs 3 s virtual past the first request and must
show the "ready" LEDs with no IWDG reset. CI runs the full form now.
"""

import argparse
import json
import os
import subprocess
import sys
import threading
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from wait_for_sim import answers_scan_probe  # noqa: E402

import cflib.crtp
from cflib.crazyflie import Crazyflie
from cflib.crazyflie.log import LogConfig
from cflib.crazyflie.syncCrazyflie import SyncCrazyflie

T0 = time.monotonic()


def say(msg):
    print(f"[{time.monotonic() - T0:6.1f} s] {msg}", flush=True)


def reduced(port, failures):
    from cflib.crtp.crtpstack import CRTPPacket
    from cflib.crtp.udpdriver import UdpDriver

    drv = UdpDriver()
    drv.connect(f'udp://127.0.0.1:{port}', None, lambda e: failures.append(f'link error: {e}'))

    def ask(port_, chan, data, want_prefix, what):
        pk = CRTPPacket()
        pk.set_header(port_, chan)
        pk.data = bytes(data)
        drv.send_packet(pk)
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            r = drv.receive_packet(1)
            if r is None:
                continue
            if r.port == port_ and r.channel == chan and bytes(r.data[:len(want_prefix)]) == bytes(want_prefix):
                say(f'{what}: {bytes(r.data).hex()}')
                return bytes(r.data)
            say(f'(other packet {r.port}/{r.channel}: {bytes(r.data).hex()})')
        failures.append(f'{what}: no answer in 60 s')
        return None

    src = ask(15, 1, [0], b'', 'link source')
    if src is not None and not src.startswith(b'Bitcraze Crazyflie'):
        failures.append(f'link source {src!r}')
    ver = ask(13, 1, [0], [0], 'protocol version')
    if ver is not None and ver[1] != 12:
        failures.append(f'protocol version {ver[1]}')
    log_info = ask(5, 0, [3], [3], 'log TOC info')
    par_info = ask(2, 0, [3], [3], 'param TOC info')
    if log_info is not None and par_info is not None:
        n_log, n_par = int.from_bytes(log_info[1:3], 'little'), int.from_bytes(par_info[1:3], 'little')
        say(f'log TOC {n_log} variables, param TOC {n_par} parameters')
        if n_log == 0 or n_par == 0 or log_info[3:7] == par_info[3:7]:
            failures.append('empty TOC or equal CRCs')
    # Walk the param TOC to mission.startX (a float the drone accepts in 0..arena), write it, read it back.
    import struct
    target = None
    for idx in range(int.from_bytes(par_info[1:3], 'little') if par_info else 0):
        item = ask(2, 0, [2, idx, 0], [2, idx, 0], f'param TOC item {idx}')
        if item is None:
            return
        group, name = item[4:].split(bytes(1))[:2]
        if (group, name) == (b'mission', b'startX'):
            target = idx
            break
    if target is None:
        failures.append('mission.startX not in the param TOC')
        return
    before = ask(2, 1, [target, 0], [target, 0], 'mission.startX read')
    new = 1.25 if before is None or abs(struct.unpack('<f', before[3:7])[0] - 1.25) > 1e-6 else 1.5
    echo = ask(2, 2, [target, 0] + list(struct.pack('<f', new)), [target, 0], 'mission.startX write (echo)')
    after = ask(2, 1, [target, 0], [target, 0], 'mission.startX read back')
    if before is not None and after is not None and echo is not None:
        b, a = struct.unpack('<f', before[3:7])[0], struct.unpack('<f', after[3:7])[0]
        say(f'mission.startX: {b} before, wrote {new}, read back {a}')
        if abs(a - new) > 1e-6:
            failures.append(f'mission.startX read back {a}, wrote {new}')
    drv.close()


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('--pil', required=True)
    ap.add_argument('--elf', required=True)
    ap.add_argument('--port', type=int, default=19860)
    ap.add_argument('--timeout', type=float, default=230.0)
    ap.add_argument('--samples', type=int, default=5)
    ap.add_argument('--virtual-seconds', type=float, default=None,
                    help="cfnav-pil's virtual-time budget, counted from cflib's first request (--serve-seconds), "
                         "so cflib's wall-clock pacing cannot race a budget that started at boot; default 120 "
                         "(full: the run ends when the checks are done), 3 (reduced: then the LEDs are checked)")
    ap.add_argument('--settle', type=float, default=0.0,
                    help='wall seconds to wait after RADIO_READY before the first request (0: at once)')
    ap.add_argument('--probe', action='store_true', help='pass --probe to cfnav-pil (registers at a panic)')
    ap.add_argument('--json', default=None)
    ap.add_argument('--pil-arg', action='append', default=[],
                    help='one more argument for cfnav-pil (repeat), e.g. --pil-arg=--no-flow')
    ap.add_argument('--reduced', action='store_true',
                    help="CI's reduced check: cflib's own UdpDriver (unmodified) asks the link source, the "
                         "protocol version and both TOCs' sizes, then reads and writes one parameter by id")
    args = ap.parse_args()
    if args.virtual_seconds is None:
        args.virtual_seconds = 3.0 if args.reduced else 120.0

    cmd = [args.pil, '--elf', args.elf, '--serve', f'127.0.0.1:{args.port}', '--seconds', '600',
           '--serve-seconds', str(args.virtual_seconds), '--no-stop', '--until-stdin-eof']
    if args.probe:
        cmd += ['--probe']
    cmd += args.pil_arg
    if args.json:
        cmd += ['--json', args.json]
    say('starting ' + ' '.join(cmd))
    pil = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    ready_line = threading.Event()

    def pump():
        for line in pil.stdout:
            print('cfnav-pil: ' + line.rstrip(), flush=True)
            if line.startswith('radio ready at'):
                ready_line.set()

    threading.Thread(target=pump, daemon=True).start()
    failures = []

    def stop_pil():
        if args.reduced and pil.poll() is None:
            # Let the run reach --virtual-seconds on its own: the LEDs' whole second of "ready" is checked too.
            try:
                pil.wait(120)
            except subprocess.TimeoutExpired:
                pass
        # Closing its stdin ends the run at the next 1 ms slice and writes the report (--until-stdin-eof).
        if pil.poll() is None:
            try:
                pil.stdin.close()
                pil.wait(20)
            except (OSError, subprocess.TimeoutExpired):
                pil.kill()
                pil.wait()

    def on_timeout():
        say(f'FAIL: timeout after {args.timeout} s wall')
        stop_pil()
        os._exit(1)

    timer = threading.Timer(args.timeout, on_timeout)
    timer.daemon = True
    timer.start()
    try:
        if not answers_scan_probe(args.port, 120):
            say('FAIL: cfnav-pil does not answer on UDP')
            stop_pil()
            return 1
        say('the bridge answers the scan probe')
        if not ready_line.wait(120):
            failures.append('the image never sent RADIO_READY')
            raise RuntimeError('no RADIO_READY')
        if args.settle > 0:
            time.sleep(args.settle)
        cflib.crtp.init_drivers()
        if args.reduced:
            reduced(args.port, failures)
            raise StopIteration
        uri = f'udp://127.0.0.1:{args.port}'
        cf = Crazyflie(rw_cache=None)
        fully = threading.Event()
        cf.fully_connected.add_callback(lambda _uri: fully.set())
        with SyncCrazyflie(uri, cf=cf) as scf:
            cf = scf.cf
            n_log = len(list(cf.log.toc.toc.items()))
            n_log_vars = sum(len(g) for g in cf.log.toc.toc.values())
            n_param = sum(len(g) for g in cf.param.toc.toc.values())
            say(f'connected: log TOC {n_log_vars} variables in {n_log} groups, param TOC {n_param} parameters')
            if n_log_vars == 0 or n_param == 0:
                failures.append('empty TOC')
            if not fully.wait(args.timeout):
                failures.append('fully_connected never fired')
            say('fully connected: every parameter value read through the emulated syslink')

            name = 'mission.startX'
            before = float(cf.param.get_value(name))
            target = 1.25 if abs(before - 1.25) > 1e-6 else 1.5
            echoed = threading.Event()
            cf.param.add_update_callback(group='mission', name='startX', cb=lambda n, v: echoed.set())
            cf.param.set_value(name, str(target))
            if not echoed.wait(60):
                failures.append(f'{name}: no echo of the write')
            echoed.clear()
            cf.param.request_param_update(name)
            if not echoed.wait(60):
                failures.append(f'{name}: no answer to the read-back')
            after = float(cf.param.get_value(name))
            say(f'{name}: {before} at connect, wrote {target}, read back {after}')
            if abs(after - target) > 1e-6:
                failures.append(f'{name} read back {after}, wrote {target}')

            samples = []
            got = threading.Event()

            def on_data(ts, data, _conf):
                samples.append((ts, dict(data)))
                if len(samples) >= args.samples:
                    got.set()

            conf = LogConfig(name='pil', period_in_ms=100)
            conf.add_variable('pm.vbat', 'float')
            conf.add_variable('stateEstimate.z', 'float')
            conf.data_received_cb.add_callback(on_data)
            cf.log.add_config(conf)
            conf.start()
            if not got.wait(max(1.0, args.timeout - (time.monotonic() - T0) - 5)):
                failures.append(f'{len(samples)} log samples, wanted {args.samples}')
            conf.stop()
            for ts, data in samples[:args.samples]:
                say(f'log sample at {ts} ms (image time): {data}')
            if len(samples) >= 2:
                spacing = [b[0] - a[0] for a, b in zip(samples, samples[1:])]
                say(f'sample spacing in image ms: {spacing[:args.samples]}')
                if any(s < 90 or s > 110 for s in spacing[:args.samples - 1]):
                    failures.append(f'log period not 100 ms of image time: {spacing}')
            if samples and abs(samples[-1][1]['pm.vbat'] - 4.0) > 1e-3:
                failures.append(f"pm.vbat = {samples[-1][1]['pm.vbat']}, the nRF reports 4.0 V")
    except StopIteration:
        pass
    except Exception as e:  # noqa: BLE001 (any cflib error is a failure of the check)
        failures.append(f'{type(e).__name__}: {e}')
    finally:
        timer.cancel()
        stop_pil()
    if pil.returncode not in (0, None):
        failures.append(f'cfnav-pil exited {pil.returncode} (not ready, or an IWDG reset)')
    if args.json and os.path.exists(args.json):
        with open(args.json) as fh:
            report = json.load(fh)
        nrf = report['nrf']
        say(f"cfnav-pil: {report['virtual_s']:.2f} s virtual in {report['wall_s']:.1f} s wall "
            f"({report['wall_s'] / max(report['virtual_s'], 1e-9):.1f} s wall per virtual s), "
            f"ready at {report['ready_at_ms']} ms, iwdg_reset_flag={report['iwdg_reset_flag']}, "
            f"UDP {report['udp_received']} in / {report['udp_sent']} out, nRF {nrf}")
        if report['iwdg_reset_flag']:
            failures.append('the watchdog reset the image')
        crashes = [l['text'] for l in report['log'] if 'panicked' in l['text'] or 'HardFault' in l['text']]
        if crashes or report['boots_logged'] != 1:
            failures.append(f"the image crashed or rebooted ({report['boots_logged']} boots): {crashes}")
        if nrf['battery_packets'] == 0:
            failures.append('the nRF sent no battery packets')
    for f in failures:
        say('FAIL: ' + f)
    if not failures:
        say('PASS (reduced): cflib UdpDriver: link source, protocol version, both TOC sizes, mission.startX '
            'written and read back through the emulated syslink' if args.reduced else
            'PASS: cflib connected to the emulated image, read both TOCs, wrote and read a parameter, logged')
    return 1 if failures else 0


if __name__ == '__main__':
    sys.exit(main())
