#!/usr/bin/env python3
"""Compare the emulated image's round trip with the SITL's (docs/pil.md).

Usage:
    python3 tools/pil/compare_sitl.py PIL.json SITL.json [--max-time-diff S] [--max-landing-err M]

PIL.json is `cfnav-pil --mission --json` (its `mission` object), SITL.json `cfnav sim --json` of the same world
and seed. Prints one markdown table row per quantity (the two values and the difference) and exits 1 when the
emulator's run did not complete, collided, or differs from the SITL's beyond the optional bounds; 2 on bad input.
"""

import json
import sys


def load(path):
    try:
        with open(path, encoding="utf-8") as f:
            return json.load(f)
    except (OSError, ValueError) as e:
        print(f"error: {path}: {e}", file=sys.stderr)
        sys.exit(2)


def landing(report, i):
    ls = report.get("landings") or []
    return ls[i] if len(ls) > i else None


def fmt(v, unit=""):
    if v is None:
        return "–"
    if isinstance(v, float):
        return f"{v:.3f}{unit}"
    return f"{v}{unit}"


def main(argv):
    args = list(argv)
    bounds = {"--max-time-diff": None, "--max-landing-err": None}
    for k in list(bounds):
        if k in args:
            i = args.index(k)
            try:
                bounds[k] = float(args[i + 1])
            except (IndexError, ValueError):
                print(f"error: {k} needs a number", file=sys.stderr)
                return 2
            del args[i : i + 2]
    if len(args) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    pil_all, sitl = load(args[0]), load(args[1])
    pil = pil_all.get("mission")
    if not isinstance(pil, dict):
        print(f"error: {args[0]} has no `mission` report (run cfnav-pil with --mission)", file=sys.stderr)
        return 2
    rows = [
        ("outcome", pil.get("outcome"), sitl.get("outcome"), None),
        ("mission state", pil.get("mission_state"), sitl.get("mission_state"), None),
        ("mission time, s", pil.get("mission_time_s"), sitl.get("mission_time_s"), "diff"),
        ("collisions", pil.get("collisions"), sitl.get("collisions"), "diff"),
        ("min clearance, m", pil.get("min_clearance_m"), sitl.get("min_clearance_m"), "diff"),
        ("distance flown, m", pil.get("distance_m"), sitl.get("distance_m"), "diff"),
    ]
    for i, name in ((0, "goal"), (1, "home")):
        a, b = landing(pil, i), landing(sitl, i)
        rows.append(
            (
                f"landing {i + 1} ({name}) error, m",
                a and a.get("error_m"),
                b and b.get("error_m"),
                "diff",
            )
        )
        rows.append((f"landing {i + 1} on pad", a and a.get("on_pad"), b and b.get("on_pad"), None))
    print(f"| quantity | emulator (seed {sitl.get('seed')}) | SITL | emulator − SITL |")
    print("|---|---|---|---|")
    for name, a, b, kind in rows:
        d = (
            a - b
            if kind == "diff" and isinstance(a, (int, float)) and isinstance(b, (int, float))
            else None
        )
        print(f"| {name} | {fmt(a)} | {fmt(b)} | {fmt(d)} |")
    ok = pil.get("outcome") == "completed" and pil.get("collisions") == 0
    t = bounds["--max-time-diff"]
    if t is not None:
        pt, st = pil.get("mission_time_s"), sitl.get("mission_time_s")
        ok = ok and pt is not None and st is not None and abs(pt - st) <= t
    m = bounds["--max-landing-err"]
    if m is not None:
        ok = ok and all((landing(pil, i) or {}).get("error_m", 1e9) <= m for i in (0, 1))
    print("verdict:", "ok" if ok else "FAIL")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
