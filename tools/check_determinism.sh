#!/usr/bin/env bash
# Decoded output must not depend on the build: encodes and decodes one generated scene with a
# debug build (opt-level 0), a release build (opt-level 3) and a release build with
# RUSTFLAGS="-C target-cpu=native", and compares the SHA-256 of the stream and of the decoded
# model. Usage: tools/check_determinism.sh [ANCHORS]   (default 20000)
set -euo pipefail
cd "$(dirname "$0")/.."
n=${1:-20000}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

cargo build -q
cargo build -q --release
RUSTFLAGS="-C target-cpu=native" cargo build -q --release --target-dir target/native

declare -A bins=(
  [opt0]=target/debug/salvq
  [opt3]=target/release/salvq
  [native]=target/native/release/salvq
)
"${bins[opt3]}" gen --anchors "$n" --seed 3 -o "$work/model.safetensors" > /dev/null
"${bins[opt3]}" gen --anchors "$n" --seed 3 --quantizer salvq -o "$work/salvq.safetensors" > /dev/null
status=0
# Two cases: the USQ model at rate 0, and the SALVQ model (learned basis, binary32 B u of
# spec §7.3) with two rate layers, decoded at the second.
for case in usq salvq; do
  ref=""
  for name in opt0 opt3 native; do
    bin=${bins[$name]}
    if [ "$case" = usq ]; then
      "$bin" encode "$work/model.safetensors" -o "$work/$name.salvq" -q
      "$bin" decode "$work/$name.salvq" -o "$work/$name.decoded.safetensors" -q
    else
      # The second case replaces the first one's files (--force).
      "$bin" encode "$work/salvq.safetensors" --rates 0,2 -o "$work/$name.salvq" -q -f
      "$bin" decode "$work/$name.salvq" --rate 2 -o "$work/$name.decoded.safetensors" -q -f
    fi
    line="$(sha256sum < "$work/$name.salvq" | cut -c1-16) $(sha256sum < "$work/$name.decoded.safetensors" | cut -c1-16)"
    echo "$case $name: stream+decoded sha256 prefixes $line"
    if [ -z "$ref" ]; then ref=$line; elif [ "$line" != "$ref" ]; then status=1; fi
  done
done
if [ "$status" -eq 0 ]; then
  echo "identical across opt-level 0, opt-level 3 and target-cpu=native ($n anchors)"
else
  echo "MISMATCH between builds" >&2
fi
exit "$status"
