#!/usr/bin/env bash
# Measures decoding one (large) stream in WebAssembly under Node, whose V8 engine and wasm32
# limits (a linear memory of 4 GiB at most) are Chromium's: the whole-buffer decode()
# (wall time, wasm linear memory after it, which is its peak since a wasm memory only grows,
# process rss and JS array buffers, then the same after reading the typed arrays out as a
# page does) and the streaming decoder fed CHUNK_BYTES at a time (wall time, peak wasm memory
# and rss after each feed). Each mode runs in its own node process, so neither sees the
# other's memory.
#
#   crates/salvq-wasm/big_decode_test.sh STREAM.salvq [CHUNK_BYTES]
#
# Builds the package with cargo build --target wasm32-unknown-unknown (into CARGO_TARGET_DIR
# if set) and wasm-bindgen --target nodejs into a temporary directory. NODE_FLAGS is passed to
# node (say NODE_FLAGS=--max-old-space-size=8192 if the JS heap, not wasm, runs out).
# Prints one line per mode: `mode=whole gaussians=N ms=T wasm_memory_bytes=M rss_bytes=R ...`,
# `mode=stream ...`, or `mode=... failed=<message>`; exits 1 if a mode failed.
set -euo pipefail

if [ $# -lt 1 ]; then
  echo "usage: $0 STREAM.salvq [CHUNK_BYTES]" >&2
  exit 2
fi
STREAM=$(realpath "$1")
CHUNK=${2:-1048576}
REPO=$(cd "$(dirname "$0")/../.." && pwd)
TARGET=${CARGO_TARGET_DIR:-$REPO/target}
NODE=${NODE:-node}
read -r -a NODE_ARGS <<< "${NODE_FLAGS:-}"

DIR=$(mktemp -d)
trap 'rm -rf "$DIR"' EXIT

echo "-- the package: cargo build --target wasm32-unknown-unknown, then wasm-bindgen --target nodejs" >&2
(cd "$REPO" && cargo build -q --release -p salvq-wasm --target wasm32-unknown-unknown)
wasm-bindgen --target nodejs --out-dir "$DIR/pkg" "$TARGET/wasm32-unknown-unknown/release/salvq_wasm.wasm"

echo "-- $STREAM: $(stat -c %s "$STREAM") bytes; node $("$NODE" --version) ${NODE_ARGS[*]:-}" >&2
status=0
for mode in whole stream; do
  flag=()
  [ "$mode" = stream ] && flag=(--stream)
  # /usr/bin/time -v, where there is one, gives the process's own peak rss too.
  if [ -x /usr/bin/time ]; then
    out=$(/usr/bin/time -f "max_rss_kib=%M" -o "$DIR/time.$mode" \
      "$NODE" "${NODE_ARGS[@]}" "$REPO/crates/salvq-wasm/big_decode.mjs" "$DIR/pkg" "$STREAM" "$CHUNK" "${flag[@]}") || status=1
    echo "$out $(tail -n 1 "$DIR/time.$mode")"
  else
    out=$("$NODE" "${NODE_ARGS[@]}" "$REPO/crates/salvq-wasm/big_decode.mjs" "$DIR/pkg" "$STREAM" "$CHUNK" "${flag[@]}") || status=1
    echo "$out"
  fi
done
exit $status
