#!/usr/bin/env bash
# End-to-end: `cfnav mission start` (crazyflie-lib over the UDP link adapter) against `cfnav sim --serve`.
#
#   bash tools/e2e/mission_start.sh            # builds the release binary first
#   CFNAV_BIN=path/to/cfnav PORT=19851 bash tools/e2e/mission_start.sh
#
# Checks (docs/formats.md (commands), docs/radio.md):
#   1. a goal outside the arena is refused: exit 2, the refusal named, the drone's console reason printed;
#   2. a mission to (5.0, 1.5) completes: exit 0, the progress ends with final state 100 (the flight completes
#      about nine times in ten, so one more flight on a fresh simulator is allowed);
#   3. Ctrl-C during the flight: mission.start = 0 written and echoed, the state goes to 40 (landing) and
#      200 (aborted), exit 130;
#   4. nothing listening: a one-line error, exit 2.
# Each case gets a fresh simulator (its battery drains with simulated time, so an old one can refuse to fly).
set -euo pipefail
cd "$(dirname "$0")/../.."

PORT=${PORT:-19851}
SPEED=${SPEED:-20}
URI="udp://127.0.0.1:$PORT"
OUT=${OUT:-target/e2e-mission}
if [ -z "${CFNAV_BIN:-}" ]; then
  cargo build -q --release -p cfnav-tools
  CFNAV_BIN="${CARGO_TARGET_DIR:-target}/release/cfnav"
fi
rm -rf "$OUT"
mkdir -p "$OUT"

passed=0
failed=0
ok() { echo "PASS: $*"; passed=$((passed + 1)); }
bad() { echo "FAIL: $*"; failed=$((failed + 1)); }

serve_pid=""
serve_n=0
stop_server() {
  if [ -n "$serve_pid" ]; then
    kill "$serve_pid" 2>/dev/null || true
    wait "$serve_pid" 2>/dev/null || true
    serve_pid=""
  fi
}
trap stop_server EXIT

# Starts a fresh simulator on $PORT and waits until it answers the 0xFF probe (cflib's scan, docs/radio.md).
start_server() {
  stop_server
  serve_n=$((serve_n + 1))
  serve_log="$OUT/serve-$serve_n.log"
  "$CFNAV_BIN" sim --serve --port "$PORT" --speed "$SPEED" >"$serve_log" 2>&1 &
  serve_pid=$!
  python3 "$(dirname "${BASH_SOURCE[0]}")/wait_for_sim.py" "$PORT" 30
}

# Runs `cfnav mission start` with the given options, output (stdout and stderr) to $1; sets $code.
mission() {
  local log=$1
  shift
  set +e
  timeout 150 "$CFNAV_BIN" mission start --uri "$URI" --toc-cache "$OUT/toc" "$@" >"$log" 2>&1
  code=$?
  set -e
  sed 's/^/    | /' "$log"
}

echo "== 1. a goal outside the arena is refused"
start_server
mission "$OUT/refused.log" --goal 50,1
if [ "$code" -eq 2 ] &&
  grep -q "error: the drone refused mission.goalX = 50.000: its echo carried the value in effect" "$OUT/refused.log" &&
  grep -q "\[drone console\] param mission.goalX refused: goal outside the arena" "$OUT/refused.log" &&
  ! grep -q "mission.start = 1" "$OUT/refused.log"; then
  ok "refused goal: exit 2, refusal and console reason shown, nothing started"
else
  bad "refused goal: exit $code (want 2 with the refusal reported)"
fi

echo "== 2. a mission to (5.0, 1.5) completes"
completed=no
for attempt in 1 2; do
  start_server
  mission "$OUT/complete-$attempt.log" --goal 5.0,1.5 --timeout 120
  if [ "$code" -eq 0 ] && grep -q "final state 100 (completed)" "$OUT/complete-$attempt.log" &&
    grep -q "set mission.goalX = 5.000: accepted" "$OUT/complete-$attempt.log" &&
    grep -q "mission.start = 1: accepted" "$OUT/complete-$attempt.log"; then
    completed=yes
    break
  fi
  echo "attempt $attempt did not complete (exit $code)"
  # Only an ended-without-completing flight (exit 1) earns a second one; anything else is a real failure.
  [ "$code" -eq 1 ] || break
done
if [ "$completed" = yes ]; then
  ok "mission completed: exit 0, final state 100 (attempt $attempt)"
else
  bad "mission did not complete (last exit $code)"
fi
if ls "$OUT"/toc/*.json >/dev/null 2>&1; then
  ok "TOC cache written ($(ls "$OUT"/toc/*.json | wc -l) files)"
else
  bad "no TOC cache file in $OUT/toc"
fi

echo "== 3. Ctrl-C aborts the mission"
start_server
log="$OUT/interrupt.log"
"$CFNAV_BIN" mission start --uri "$URI" --toc-cache "$OUT/toc" --goal 5.0,1.5 >"$log" 2>&1 &
mission_pid=$!
# Interrupt once the drone is navigating (state 11), at most 20 s from now.
for _ in $(seq 200); do
  grep -q "state  11" "$log" && break
  kill -0 "$mission_pid" 2>/dev/null || break
  sleep 0.1
done
kill -INT "$mission_pid" 2>/dev/null || true
set +e
wait "$mission_pid"
code=$?
set -e
sed 's/^/    | /' "$log"
if [ "$code" -eq 130 ] &&
  grep -q "mission.start = 0: accepted (echo 0)" "$log" &&
  grep -q "state  40 landing where it is" "$log" &&
  grep -q "final state 200 (aborted by the user, landed)" "$log" &&
  grep -q "mission.start = 0: aborting" "$serve_log"; then
  ok "Ctrl-C: mission.start = 0 echoed, state 40 then 200, exit 130"
else
  bad "Ctrl-C: exit $code (want 130 with mission.start = 0, state 40 and 200)"
fi

echo "== 4. nothing listening"
stop_server
mission "$OUT/no-server.log" --goal 5.0,1.5
if [ "$code" -eq 2 ] && grep -q "nothing listens there (connection refused)" "$OUT/no-server.log"; then
  ok "no simulator: exit 2, one-line error"
else
  bad "no simulator: exit $code (want 2)"
fi

echo "mission-e2e: $passed passed, $failed failed"
[ "$failed" -eq 0 ]
