#!/usr/bin/env bash
# cargo for the emulator (cfnav-pil), e.g. `bash tools/pil/cargo.sh build`, `... test`, `... clippy --all-targets`.
#
# tools/pil is its own cargo workspace because it builds rsemu with a fix of ours: the pinned upstream crate
# (crates.io, checked against its sha256) is unpacked into tools/pil/vendor/ (ignored by git) and the files in
# tools/pil/patches/ are applied to it; tools/pil/Cargo.toml's [patch.crates-io] points there. Done once, and
# again whenever a patch changes. Build products go to the main target directory (target/debug/cfnav-pil),
# or to $CARGO_TARGET_DIR.
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
root=$(cd "$here/../.." && pwd)
version=0.0.7
# The checksum crates.io publishes for rsemu 0.0.7 (the one Cargo.lock files record).
sha256=aabb47768dbdd5420ee71ef4c717102ff94cf6030f32d8cec27e1b41fd863a19
vendor="$here/vendor/rsemu-$version"
stamp="$vendor/.cfnav-patches"
want=$(cat "$here"/patches/*.patch | sha256sum | cut -d' ' -f1)
if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ]; then
  crate=""
  for c in "${CARGO_HOME:-$HOME/.cargo}"/registry/cache/*/"rsemu-$version.crate"; do
    [ -f "$c" ] && crate=$c
  done
  tmp=$(mktemp -d)
  trap 'rm -rf "$tmp"' EXIT
  if [ -z "$crate" ]; then
    curl -fsSL --retry 3 -o "$tmp/rsemu.crate" "https://static.crates.io/crates/rsemu/rsemu-$version.crate"
    crate=$tmp/rsemu.crate
  fi
  echo "$sha256  $crate" | sha256sum -c --quiet - || { echo "rsemu-$version.crate: checksum mismatch" >&2; exit 1; }
  rm -rf "$vendor"
  mkdir -p "$here/vendor"
  tar xzf "$crate" -C "$here/vendor"
  for p in "$here"/patches/*.patch; do
    # GIT_DIR: apply to these files, not to the cfnav repository the directory sits in.
    (cd "$vendor" && GIT_DIR=/nonexistent git apply -p1 "$p")
  done
  echo "$want" > "$stamp"
  echo "rsemu $version unpacked in tools/pil/vendor with $(ls "$here"/patches/*.patch | wc -l) patch(es) applied" >&2
fi
[ $# -gt 0 ] || set -- build
sub=$1
shift
case "$sub" in
  fmt) exec cargo fmt --manifest-path "$here/Cargo.toml" "$@" ;;
  *) exec cargo "$sub" --manifest-path "$here/Cargo.toml" --target-dir "${CARGO_TARGET_DIR:-$root/target}" "$@" ;;
esac
