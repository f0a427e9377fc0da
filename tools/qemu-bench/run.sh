#!/usr/bin/env bash
# Build the planner benchmark for the Cortex-M4 (workspace release profile, as flown) and run it under QEMU's
# mps2-an386 with `-icount shift=10`, which makes its instruction counts exact (see src/mcu.rs).
#
# Usage: tools/qemu-bench/run.sh [--check]      (from any directory; honours CARGO_TARGET_DIR)
#   --check   also compare against the targets and exit 1 if any is missed:
#             first plan, and first plan + the first replan after it, <= 3 000 000 instructions each,
#             median 20 cm obstacle replan <= 500 000 instructions,
#             grid + planner <= 49 152 B (48 KiB), the worst 1 kHz control step <= 30 000 instructions
#             (27 % of 168 MHz at CPI 1.5; 28 000 before the 10-state EKF), one planner slice <= 21 M (the watchdog's
#             500 ms thread-mode allowance at CPI 3 with a quarter of the core taken by interrupts), the map
#             fixes' EKF update <= 24 000 and their four ray casts <= 60 000 instructions per sweep.
# Environment: QEMU_TIMEOUT (seconds, default 300), QEMU (default qemu-system-arm).
# Exit status: 0 on success; 1 on a benchmark failure or a missed target; 2 on bad usage or a missing tool.
set -euo pipefail

check=0
for arg in "$@"; do
    case "$arg" in
        --check) check=1 ;;
        -h | --help)
            sed -n '2,13p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'
            exit 0
            ;;
        *)
            echo "run.sh: unknown argument '$arg' (expected --check or --help)" >&2
            exit 2
            ;;
    esac
done

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
# A relative CARGO_TARGET_DIR means relative to the caller's directory; cargo runs from the repository root below.
if [[ -n "${CARGO_TARGET_DIR:-}" && "${CARGO_TARGET_DIR}" != /* ]]; then
    export CARGO_TARGET_DIR="$PWD/$CARGO_TARGET_DIR"
fi
qemu="${QEMU:-qemu-system-arm}"
limit="${QEMU_TIMEOUT:-300}"
for tool in cargo "$qemu" timeout; do
    if ! command -v "$tool" > /dev/null; then
        echo "run.sh: '$tool' not found (needs cargo with the thumbv7em-none-eabihf target, and QEMU >= 7.2)" >&2
        exit 2
    fi
done

cd "$root"
# The executable's path comes from cargo itself, so any target-dir setting (env or config) is honoured.
artifacts="$(cargo build --release -p qemu-bench --target thumbv7em-none-eabihf \
    --message-format=json-render-diagnostics)"
elf="$(printf '%s\n' "$artifacts" | grep '"reason":"compiler-artifact"' | grep '"name":"qemu-bench"' \
    | grep -o '"executable":"[^"]*"' | tail -n 1 | cut -d'"' -f4 || true)"
if [[ -z "$elf" || ! -f "$elf" ]]; then
    echo "run.sh: cargo did not report the qemu-bench executable" >&2
    exit 1
fi

log="$(mktemp)"
trap 'rm -f "$log"' EXIT
echo "+ $qemu -M mps2-an386 -nographic -semihosting-config enable=on,target=native -icount shift=10 -kernel $elf" >&2
status=0
timeout "$limit" "$qemu" -M mps2-an386 -nographic -semihosting-config enable=on,target=native -icount shift=10 \
    -kernel "$elf" < /dev/null | tee "$log" || status=$?
if ((status == 124)); then
    echo "run.sh: QEMU timed out after ${limit} s" >&2
    exit 1
elif ((status != 0)); then
    echo "run.sh: the benchmark failed (QEMU exit status $status)" >&2
    exit 1
elif ! grep -qx 'result=ok' "$log"; then
    echo "run.sh: the benchmark did not report result=ok" >&2
    exit 1
fi

((check)) || exit 0

value() { # the value of `key=` in the log, or empty
    sed -n "s/^$1=\([0-9][0-9]*\)\r*\$/\1/p" "$log" | tail -n 1
}
failed=0
target() { # name key limit unit
    local v
    v="$(value "$2")"
    if [[ -z "$v" ]]; then
        echo "FAIL $1: '$2' missing from the output"
        failed=1
    elif ((v <= $3)); then
        echo "PASS $1: $v <= $3 $4"
    else
        echo "FAIL $1: $v > $3 $4"
        failed=1
    fi
}
target "first plan" first_plan_instructions 3000000 instructions
target "first plan + first replan" first_plan_and_first_replan_instructions 3000000 instructions
target "median 20 cm obstacle replan" box_instructions_median 500000 instructions
target "grid + planner RAM" ram_total_bytes 49152 bytes
target "worst control step (27 % of the core at 1 kHz, CPI 1.5)" control_step_instructions_max 30000 instructions
target "planner slice (watchdog thread-mode allowance)" planner_slice_instructions 21000000 instructions
target "map fixes' EKF update per sweep (one heavy input of a control step)" map_fix_update_instructions_max 24000 instructions
target "map fixes' ray casts per sweep (thread mode)" map_fix_cast_instructions_max 60000 instructions
exit "$failed"
