#!/usr/bin/env bash
# Runs CI's emulator jobs in the background, WORKERS at a time (default 2: each cfnav-pil run is one
# single-threaded process, so one core each), while CI's other steps go on.
#
#   bash tools/pil/queue.sh JOBS DIR [WORKERS]
#
# JOBS: one job per line, "NAME PROGRAM ARGS..." (words split as xargs splits them; '#' lines and blank lines
# are skipped), longest first so the two workers finish close together. For each job it writes DIR/NAME.log
# (stdout and stderr), DIR/NAME.wall (seconds) and, last, DIR/NAME.rc (the exit status): a waiter polls for
# the .rc file (the `pil` step, xtask/src/steps.rs). Run it in its own process group, so one kill of the
# group stops every job.
set -uo pipefail
jobs=$1
export QUEUE_DIR=$2
workers=${3:-2}
mkdir -p "$QUEUE_DIR"
run_job() {
  local name=$1
  shift
  local start=$SECONDS rc=0
  "$@" >"$QUEUE_DIR/$name.log" 2>&1 || rc=$?
  echo $((SECONDS - start)) >"$QUEUE_DIR/$name.wall"
  echo "$rc" >"$QUEUE_DIR/$name.rc.part" && mv "$QUEUE_DIR/$name.rc.part" "$QUEUE_DIR/$name.rc"
}
export -f run_job
grep -Ev '^[[:space:]]*(#|$)' "$jobs" | xargs -P "$workers" -L 1 bash -c 'run_job "$@"' run_job
