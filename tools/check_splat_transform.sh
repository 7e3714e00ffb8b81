#!/usr/bin/env bash
# Checks that a PLY file written by `salvq export-ply` (spec Annex C.3) is read by a common
# third-party tool, PlayCanvas splat-transform (npm @playcanvas/splat-transform), with every
# Gaussian kept: its summary, and round trips through .spz and .compressed.ply back to .ply.
# The PLY files splat-transform writes (other property order) are then rendered by
# `salvq render`, which reads properties by name.
#
#   tools/check_splat_transform.sh            # builds salvq (release) with cargo
#   SALVQ=path/to/salvq tools/check_splat_transform.sh
#
# Installs splat-transform into a temporary folder (nothing global). Exits 0 and prints
# "skipped: npm not available" when npm is missing.
set -euo pipefail

if ! command -v npm >/dev/null 2>&1; then
    echo "skipped: npm not available"
    exit 0
fi

root=$(cd "$(dirname "$0")/.." && pwd)
version=${SPLAT_TRANSFORM_VERSION:-2.7.1}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

salvq=${SALVQ:-}
if [ -z "$salvq" ]; then
    (cd "$root" && cargo build --release --quiet)
    salvq="${CARGO_TARGET_DIR:-$root/target}/release/salvq"
fi
# The checks run in a scratch folder: make a relative path absolute first.
case "$salvq" in
    /*) ;;
    *) salvq="$PWD/$salvq" ;;
esac

echo "installing @playcanvas/splat-transform@$version into a temporary folder"
npm install --prefix "$work/npm" --no-audit --no-fund --loglevel=error \
    "@playcanvas/splat-transform@$version" >/dev/null
st="$work/npm/node_modules/.bin/splat-transform"
echo "$("$st" --version 2>&1 | sed -n 1p)"

cd "$work"
"$salvq" gen --anchors 2000 --seed 1 -o model.safetensors >/dev/null
"$salvq" encode model.safetensors -o scene.salvq >/dev/null 2>&1
"$salvq" export-ply scene.salvq -o scene.ply

# The vertex count a PLY header declares. No stage of a pipeline here stops reading early
# (grep -m, head -n): under pipefail the stage before it would die of SIGPIPE (exit 141)
# whenever it had not finished writing, which failed CI once.
count() { head -c 65536 "$1" | tr -d '\r' | grep -a '^element vertex ' | cut -d ' ' -f 3 | sed -n 1p; }

n=$(count scene.ply)
echo "salvq export-ply: $n Gaussians in scene.ply"
failed=0
check() { # name, count
    if [ "$2" = "$n" ]; then
        echo "ok   $1: $2 Gaussians"
    else
        echo "FAIL $1: $2 Gaussians, expected $n"
        failed=1
    fi
}

rows=$("$st" -w scene.ply --summary null 2>/dev/null | grep -a 'Row Count' | sed -n 1p | tr -dc '0-9')
check "splat-transform --summary of scene.ply" "$rows"

for format in spz compressed.ply; do
    "$st" -q -w scene.ply "scene.$format"
    "$st" -q -w "scene.$format" "back.$format.ply"
    check "scene.ply -> scene.$format -> back.$format.ply" "$(count "back.$format.ply")"
    if "$salvq" render "back.$format.ply" -o "back.$format.png" --width 64 --height 48 >/dev/null; then
        echo "ok   salvq render back.$format.ply"
    else
        echo "FAIL salvq render back.$format.ply"
        failed=1
    fi
done

if [ "$failed" = 0 ]; then
    echo "splat-transform check passed"
else
    echo "splat-transform check FAILED"
fi
exit "$failed"
