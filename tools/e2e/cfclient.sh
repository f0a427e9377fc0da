#!/usr/bin/env bash
# The stock cfclient (PyPI) and cflib against `cfnav sim --serve`, for CI (.ci/run) and by hand:
#   bash tools/e2e/cfclient.sh            # installs what is missing, serves on 19853, runs both checks
# 1. tools/e2e/cflib_stock_names.py: cflib alone (decks, every cfclient log block, PositionHlCommander(PID),
#    MotionCommander's estimator reset);
# 2. tools/e2e/cfclient_gui.py: cfclient's own window under Xvfb from a fresh config (connect, every
#    parameter shown, an edit read back, battery and state estimate shown, the Supervisor box on the ground
#    and flying a mission, no exception), screenshots in
#    target/cfclient/.
# The simulator must listen inside 19850-19859, the ports cflib's UDP scan probes (cfclient connects to what
# its scan lists). Each check is bounded in time; a failure says which check and why.
set -euo pipefail
cd "$(dirname "$0")/../.."
PORT=${PORT:-19853}
URI="udp://127.0.0.1:$PORT"

# Xvfb and the X/xcb libraries Qt 6's xcb platform plugin loads (PyQt6 wheels bundle Qt, not these).
apt_pkgs=(xvfb xauth libxkbcommon-x11-0 libxcb-icccm4 libxcb-image0 libxcb-keysyms1 libxcb-randr0
  libxcb-render-util0 libxcb-shape0 libxcb-xinerama0 libxcb-xfixes0 libxcb-cursor0 libxcb-xkb1 libegl1 libgl1
  libfontconfig1 libdbus-1-3 libglib2.0-0 fonts-dejavu-core)
missing=()
for p in "${apt_pkgs[@]}"; do dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p"); done
if [ ${#missing[@]} -gt 0 ]; then
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi
python3 -c 'import cfclient' 2>/dev/null || python3 -m pip install -q cfclient
python3 -m pip show cflib cfclient 2>/dev/null | grep -E '^(Name|Version)' | paste -sd' '

cargo build -q --release -p cfnav-tools
mkdir -p target/cfclient
"${CARGO_TARGET_DIR:-target}/release/cfnav" sim --serve --port "$PORT" >target/cfclient/serve.log 2>&1 &
serve_pid=$!
trap 'kill "$serve_pid" 2>/dev/null || true' EXIT
python3 tools/e2e/wait_for_sim.py "$PORT" 30
show_serve_log() { echo "--- the simulator's log (last 40 lines) ---"; tail -n 40 target/cfclient/serve.log; }

if ! timeout 60 python3 tools/e2e/cflib_stock_names.py --uri "$URI"; then
  echo "cflib check of the stock parameter/log names failed (simulator log: target/cfclient/serve.log)"
  show_serve_log
  exit 1
fi
# A fresh simulator state is not needed: the GUI check reads what is there and restores nothing.
if ! timeout 120 xvfb-run -a -s "-screen 0 1600x1000x24" \
  python3 tools/e2e/cfclient_gui.py --uri "$URI" --timeout 90 --shots target/cfclient; then
  echo "stock cfclient check failed (screenshots in target/cfclient/, simulator log: target/cfclient/serve.log)"
  show_serve_log
  exit 1
fi
kill "$serve_pid" 2>/dev/null || true
wait "$serve_pid" 2>/dev/null || true
trap - EXIT
