#!/usr/bin/env bash
# Builds tools/fma_check.c as a C compiler that fuses multiplies and adds would (GCC, -O2,
# -march=native, -ffp-contract=fast) and runs it: spec §3.6 step 3 in binary64 must not move
# under fusion (exit 1 otherwise).
set -euo pipefail
cd "$(dirname "$0")/.."
out=$(mktemp)
trap 'rm -f "$out"' EXIT
${CC:-gcc} -O2 -march=native -ffp-contract=fast -o "$out" tools/fma_check.c -lm
"$out"
