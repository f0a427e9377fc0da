#!/usr/bin/env bash
# The map on the PC, end to end: a mission on `cfnav sim --serve --map-json`, the map
# downloaded with `cfnav map` once while the drone flies and once after it has landed, each compared cell for
# cell with the simulator's own map of the same moment (compare_map.py), the plot drawn, and cflib's memory
# API listing and reading the same map unmodified (cflib_map.py).
# Needs the release `cfnav` built (or CFNAV=path) and cflib installed. PORT (default 19854); files in
# target/e2e-map/.
set -euo pipefail
cd "$(dirname "$0")/../.."
PORT=${PORT:-19854}
uri="udp://127.0.0.1:$PORT"
cfnav="${CFNAV:-${CARGO_TARGET_DIR:-target}/release/cfnav}"
out=target/e2e-map
rm -rf "$out"
mkdir -p "$out"

"$cfnav" sim --serve --port "$PORT" --speed 4 --map-json "$out/sim_map.json" 2>"$out/serve.log" &
serve_pid=$!
trap 'kill "$serve_pid" 2>/dev/null || true' EXIT
python3 tools/e2e/wait_for_sim.py "$PORT" 60

state() { python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["mission_state"])' "$1"; }
occupied() { python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["cells"].count(3))' "$1"; }

# Before the mission: the map memory is there, and empty.
"$cfnav" map --uri "$uri" --json "$out/idle.json"
python3 tools/e2e/cflib_map.py --uri "$uri" --start

# While flying: download until the drone is navigating (or searching, approaching) and has mapped something,
# then compare. (The first download in state 11 can come before the first sweep is written: on a loaded
# machine it did, and the check then failed on "no occupied cell".)
flying=0
for _ in $(seq 1 60); do
  "$cfnav" map --uri "$uri" --json "$out/flying.json" 2>>"$out/map.log"
  s=$(state "$out/flying.json")
  if { { [ "$s" -ge 11 ] && [ "$s" -le 13 ]; } || { [ "$s" -ge 21 ] && [ "$s" -le 23 ]; }; } \
    && [ "$(occupied "$out/flying.json")" -gt 0 ]; then flying=1; break; fi
  if [ "$s" -ge 100 ]; then break; fi
  sleep 0.5
done
[ "$flying" = 1 ] || { echo "FAIL: never downloaded the map while flying (last state $s)"; exit 1; }
cp "$out/sim_map.json" "$out/sim_map_flying.json"
echo "while flying (mission.state $s):"
python3 tools/e2e/compare_map.py "$out/flying.json" "$out/sim_map_flying.json" --flying

# After the mission: wait for a final state, then download, plot and compare.
for _ in $(seq 1 120); do
  "$cfnav" map --uri "$uri" --json "$out/landed.json" 2>>"$out/map.log"
  s=$(state "$out/landed.json")
  [ "$s" -ge 100 ] && break
  sleep 1
done
[ "$s" -ge 100 ] || { echo "FAIL: the mission did not end (state $s)"; exit 1; }
"$cfnav" map --uri "$uri" --json "$out/landed.json" --plot "$out/map.png"
cp "$out/sim_map.json" "$out/sim_map_landed.json"
echo "after landing (mission.state $s):"
python3 tools/e2e/compare_map.py "$out/landed.json" "$out/sim_map_landed.json"

# cflib's memory API, unmodified: lists the map memory and reads the same map.
python3 tools/e2e/cflib_map.py --uri "$uri" --sim-map "$out/sim_map.json"
kill "$serve_pid" 2>/dev/null || true
wait "$serve_pid" 2>/dev/null || true
trap - EXIT
echo "map on the PC: OK"
