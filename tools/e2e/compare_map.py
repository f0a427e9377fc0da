#!/usr/bin/env python3
"""Compare a downloaded map (`cfnav map --json`, or the dict `cflib_map.py` decodes) with the simulator's own
map of the same moment (`cfnav sim --serve --map-json FILE`), cell for cell, path point for path point, pad for
pad. The cell codes of the download (0 unknown, 1 free, 2 inflated, 3 occupied) are checked against the rule
of docs/map-memory.md applied here to the simulator's per-cell flags (occupied, blocked, unknown), which the
simulator reads through the grid's own queries, not through the map memory's serialiser.

Usage: compare_map.py DOWNLOAD.json SIM_MAP.json [--flying]    (exit 0 equal, 1 not)
"""

import json
import struct
import sys


def f32(v):
    """`v` rounded to the f32 it came from (JSON and Python carry f32 values as decimals or doubles)."""
    return struct.unpack('<f', struct.pack('<f', v))[0]


def expected_codes(sim):
    return [3 if o else 2 if b else 0 if u else 1
            for o, b, u in zip(sim['occupied'], sim['blocked'], sim['unknown'])]


def compare(got, sim):
    """Returns a list of differences (empty when equal)."""
    diffs = []
    if got['crc32'] != sim['crc32']:
        diffs.append(f"snapshot CRC {got['crc32']:#010x} downloaded, {sim['crc32']:#010x} in the simulator's dump")
    for k in ('width', 'height', 'mission_state'):
        if got[k] != sim[k]:
            diffs.append(f'{k}: {got[k]} downloaded, {sim[k]} in the simulator')
    want = expected_codes(sim)
    if len(got['cells']) != len(want):
        diffs.append(f"{len(got['cells'])} cells downloaded, {len(want)} in the simulator")
    else:
        bad = [i for i, (a, b) in enumerate(zip(got['cells'], want)) if a != b]
        if bad:
            w = sim['width']
            diffs.append(f'{len(bad)} cells differ, first at (x, y) = {(bad[0] % w, bad[0] // w)}: '
                         f"{got['cells'][bad[0]]} vs {want[bad[0]]}")
    if [list(p) for p in got['path']] != [list(p) for p in sim['path']][:64]:
        diffs.append(f"path {got['path']} downloaded, {sim['path']} in the simulator")
    want_pads = []
    if sim['pad_estimate'] is not None:
        x, y, c, locked = sim['pad_estimate']
        want_pads.append(('estimate', x, y, c, locked))
    for kind, lock in zip(('goal_lock', 'home_lock'), sim['pad_locks']):
        if lock is not None:
            want_pads.append((kind, lock[0], lock[1], 1.0, True))
    got_pads = [(p['kind'], p['x_m'], p['y_m'], p['confidence'], p['locked']) for p in got['pads']]
    if len(got_pads) != len(want_pads) or any(
            a[0] != b[0] or f32(a[1]) != f32(b[1]) or f32(a[2]) != f32(b[2]) or abs(a[3] - min(max(b[3], 0.0), 1.0)) > 0.5 / 255 + 1e-6
            or a[4] != b[4] for a, b in zip(got_pads, want_pads)):
        diffs.append(f'pads {got_pads} downloaded, {want_pads} in the simulator')
    return diffs


def main():
    args = [a for a in sys.argv[1:] if not a.startswith('--')]
    flying = '--flying' in sys.argv
    got = json.load(open(args[0]))
    sim = json.load(open(args[1]))
    diffs = compare(got, sim)
    counts = [got['cells'].count(k) for k in range(4)]
    if flying and not (11 <= got['mission_state'] <= 13 or 21 <= got['mission_state'] <= 23):
        diffs.append(f"mission.state {got['mission_state']}: not a flying state")
    if counts[3] == 0:
        diffs.append('no occupied cell: the drone has mapped nothing')
    if diffs:
        for d in diffs:
            print('FAIL:', d)
        return 1
    print(f"equal cell for cell: {got['width']} x {got['height']} cells ({counts[3]} occupied, {counts[2]} inflated, "
          f"{counts[1]} free, {counts[0]} unknown), path {len(got['path'])} points, {len(got['pads'])} pad records, "
          f"mission.state {got['mission_state']}, CRC {got['crc32']:#010x}")
    return 0


if __name__ == '__main__':
    sys.exit(main())
