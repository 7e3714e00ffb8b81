#!/usr/bin/env bash
# Installs wasm-bindgen-cli 0.2.130 (the version salvq-wasm pins: `wasm-bindgen = "=0.2.130"`)
# from a committed lockfile, so that every machine builds the same dependency versions.
# `cargo install wasm-bindgen-cli --version 0.2.130 --locked` uses the crate's own Cargo.lock,
# which names webpki-roots 1.0.11; a registry mirror that lacks it fails to resolve. Without
# --locked, cargo picks whatever is newest that day. wasm-bindgen-cli.lock beside this script
# is the crate's Cargo.lock with that one package moved to 1.0.10 (`cargo update -p
# webpki-roots --precise 1.0.10`); everything else is as wasm-bindgen 0.2.130 shipped it.
# usage: crates/salvq-wasm/install_wasm_bindgen_cli.sh [cargo install options, e.g. --root DIR]
# Needs curl, tar, sha256sum; the crate comes from static.crates.io (sha256 checked).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
version=0.2.130
sha256=c37f6904387d19a319525c74af274c73912f3871c35555aa49f3ea64ebb2fc7a
src=$(mktemp -d)
trap 'rm -rf "$src"' EXIT
curl -sSfL -o "$src/cli.crate" \
  "https://static.crates.io/crates/wasm-bindgen-cli/wasm-bindgen-cli-$version.crate"
echo "$sha256  $src/cli.crate" | sha256sum -c --quiet
tar -xzf "$src/cli.crate" -C "$src"
cp "$here/wasm-bindgen-cli.lock" "$src/wasm-bindgen-cli-$version/Cargo.lock"
cargo install --locked --path "$src/wasm-bindgen-cli-$version" --bin wasm-bindgen "$@"
