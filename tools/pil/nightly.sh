#!/usr/bin/env bash
# The nightly-length processor-in-the-loop job (docs/pil.md): the unmodified firmware
# image flies the default world's round trip in the emulator on each noise seed given, and each run is compared
# with the SITL's run of the same world and seed (tools/pil/compare_sitl.py). Too long for CI (≈ 65 s virtual
# per seed, ≈ 10 min wall on an idle core); run it from a clone that has run .ci/run once (the toolchain and
# rsemu are then in place):
#
#     bash tools/pil/nightly.sh            # seeds 1 2 3
#     bash tools/pil/nightly.sh 4 5        # other seeds
#
# Exit 0 when every seed completed without a collision in the emulator, 1 otherwise. Reports go to
# target/pil/nightly/{pil,sitl}-S.json, the comparison tables to target/pil/nightly/compare-S.md.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/../.."
seeds=("$@")
[ ${#seeds[@]} -gt 0 ] || seeds=(1 2 3)
target=${CARGO_TARGET_DIR:-target}
out=target/pil/nightly
mkdir -p "$out"
cargo build -q --release -p cfnav --bin firmware --features firmware --target thumbv7em-none-eabihf
cargo build -q --release -p cfnav-tools
bash tools/pil/cargo.sh build -q
elf=$target/thumbv7em-none-eabihf/release/firmware
status=0
for s in "${seeds[@]}"; do
  "$target/release/cfnav" sim --world worlds/default.toml --seed "$s" --json "$out/sitl-$s.json" > /dev/null || true
  start=$SECONDS
  "$target/debug/cfnav-pil" --elf "$elf" --mission --seed "$s" --json "$out/pil-$s.json" > "$out/pil-$s.log" 2>&1 || true
  echo "seed $s: $((SECONDS - start)) s wall"
  python3 tools/pil/compare_sitl.py "$out/pil-$s.json" "$out/sitl-$s.json" | tee "$out/compare-$s.md" || status=1
done
exit $status
