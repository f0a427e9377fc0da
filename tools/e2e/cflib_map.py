#!/usr/bin/env python3
"""The map memory through unmodified cflib (>= 0.1.32): its memory API lists and reads it.

  cflib_map.py --uri udp://127.0.0.1:19854 --start          connect, write mission.start = 1, disconnect
  cflib_map.py --uri udp://127.0.0.1:19854 --sim-map FILE   list and read the map, compare with FILE

The check: `cf.mem.get_mems(0xC4)` lists exactly one memory (cflib makes a plain MemoryElement of a type it
does not know), `cf.mem.read` + `mem_read_cb` read its whole size in cflib's 24-byte chunks; the bytes carry
the magic "CFNM", version 1, and a CRC-32 (zlib.crc32) that matches; the cells, path and pads decoded here from
docs/map-memory.md equal the simulator's own map of that moment (compare_map.py). Exit 0 on success.
"""

import argparse
import os
import struct
import sys
import threading
import zlib

import cflib.crtp
from cflib.crazyflie import Crazyflie
from cflib.crazyflie.syncCrazyflie import SyncCrazyflie

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from compare_map import compare  # noqa: E402

MAP_TYPE = 0xC4


def decode(b):
    """The map memory's bytes (docs/map-memory.md, version 1) as compare_map.py's dict."""
    assert b[:4] == b'CFNM', f'magic {b[:4]!r}'
    assert b[4] == 1 and b[5] == 32 and b[6] == 2, f'version/header/bits {b[4]}, {b[5]}, {b[6]}'
    crc, total, w, h, cell_mm, ox, oy, npath, npads, flags = struct.unpack_from('<IIHHHhhHBB', b, 8)
    assert crc == zlib.crc32(bytes(b[12:total])), 'CRC mismatch (the map changed during the read)'
    n = w * h
    cells = [(b[32 + i // 4] >> (2 * (i % 4))) & 3 for i in range(n)]
    at = 32 + (n + 3) // 4
    path = [list(struct.unpack_from('<HH', b, at + 4 * k)) for k in range(npath)]
    at += 4 * npath
    pads = []
    for k in range(npads):
        x, y, conf, kind, pflags = struct.unpack_from('<ffBBB', b, at + 12 * k)
        pads.append({'kind': ['estimate', 'goal_lock', 'home_lock'][kind], 'x_m': x, 'y_m': y,
                     'confidence': conf / 255, 'locked': bool(pflags & 1)})
    assert 32 + (n + 3) // 4 + 4 * npath + 12 * npads == total
    return {'width': w, 'height': h, 'cell_size_m': cell_mm / 1000, 'mission_state': b[7], 'crc32': crc,
            'cells': cells, 'path': path, 'pads': pads}


def read_memory(cf, mem, timeout=20.0):
    done = threading.Event()
    got = {}

    def ok(m, addr, data):
        if m.id == mem.id:
            got['data'] = bytes(data)
            done.set()

    def failed(m, addr, data):
        if m.id == mem.id:
            got['error'] = addr
            done.set()

    cf.mem.mem_read_cb.add_callback(ok)
    cf.mem.mem_read_failed_cb.add_callback(failed)
    try:
        cf.mem.read(mem, 0, mem.size)
        if not done.wait(timeout):
            raise RuntimeError(f'no answer reading the map memory within {timeout} s')
    finally:
        cf.mem.mem_read_cb.remove_callback(ok)
        cf.mem.mem_read_failed_cb.remove_callback(failed)
    if 'error' in got:
        raise RuntimeError(f"the map read failed at {got['error']}")
    return got['data']


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--uri', default='udp://127.0.0.1:19854')
    ap.add_argument('--start', action='store_true', help='write mission.start = 1 and leave')
    ap.add_argument('--sim-map', help="the simulator's --map-json file to compare with")
    args = ap.parse_args()
    cflib.crtp.init_drivers()
    with SyncCrazyflie(args.uri, cf=Crazyflie(rw_cache=None)) as scf:
        cf = scf.cf
        if args.start:
            done = threading.Event()
            cf.param.add_update_callback(group='mission', name='start', cb=lambda n, v: done.set())
            cf.param.set_value('mission.start', 1)
            if not done.wait(5):
                print('FAIL: no echo for mission.start = 1')
                return 1
            print('mission.start = 1 written')
            return 0
        mems = cf.mem.get_mems(MAP_TYPE)
        if len(mems) != 1:
            print(f'FAIL: cf.mem.get_mems({MAP_TYPE:#x}) lists {len(mems)} memories; all: '
                  f'{[str(m) for m in cf.mem.mems]}')
            return 1
        mem = mems[0]
        print(f'cflib lists {mem} (type {mem.type:#x})')
        for attempt in range(5):
            data = read_memory(cf, mem)
            try:
                got = decode(data)
                break
            except AssertionError as e:
                if 'CRC' not in str(e) or attempt == 4:
                    print(f'FAIL: {e}')
                    return 1
        print(f"read {len(data)} bytes: {got['width']} x {got['height']} cells, path {len(got['path'])} points, "
              f"{len(got['pads'])} pads, mission.state {got['mission_state']}")
        if args.sim_map:
            import json
            diffs = compare(got, json.load(open(args.sim_map)))
            if diffs:
                for d in diffs:
                    print('FAIL:', d)
                return 1
            print("equal cell for cell to the simulator's own map")
    return 0


if __name__ == '__main__':
    sys.exit(main())
