#!/usr/bin/env bash
# Bytes and milliseconds to the first frame over a slow link: the salvq viewer page
# (www/index.html) loading a scene's progressive .salvq file against the PlayCanvas engine
# loading the same scene's SOG (splat-transform's .sog bundle), both in headless Chromium,
# in the same engine, from the same camera, through the same throttled server
# (tools/viewer_check/throttled_server.py: the scene files and the wasm package at MBIT
# Mbit/s after LATENCY ms; the engine's own script is served at once to both pages).
# Each page is loaded RUNS times, in turn; the table gives medians, from the moment the page
# asks for the scene, of:
#  - salvq: the first tiles drawn, the whole scene first drawn (at its coarsest rate for a
#    progressive file), each finer rate drawn, the finest drawn; bytes received at each;
#  - SOG: the asset ready (the whole file fetched and its images decoded), its first frame.
# Fails unless the salvq file is progressive and its whole scene was drawn before all of its
# bytes were in (the coarsest rate's prefix), and every run drew every Gaussian.
# usage: crates/salvq-wasm/first_frame_test.sh SCENE.ply
#   MBIT=50, LATENCY=20, RUNS=3, WASM_CACHED=1 (the wasm package served at once, as from a
#   visit before: only the scene files cross the link), STREAM=file.salvq (encoded from SCENE earlier; default: encode
#   SCENE with the encoder's defaults), SOG=file.sog (default: splat-transform SCENE file.sog),
#   SPLAT_TRANSFORM (default: npm install @playcanvas/splat-transform@2.7.1 into WORK),
#   WORK=dir keeps the files. Needs what browser_test.sh needs.
set -euo pipefail
REPO=$(cd "$(dirname "$0")/../.." && pwd)
TARGET=${CARGO_TARGET_DIR:-$REPO/target}
case "$TARGET" in /*) ;; *) TARGET=$REPO/$TARGET ;; esac
SALVQ=${SALVQ:-$TARGET/release/salvq}
SCENE=${1:?usage: first_frame_test.sh SCENE.ply}
WORK=${WORK:-$(mktemp -d)}
PORT=${PORT:-8767}
MBIT=${MBIT:-50}
LATENCY=${LATENCY:-20}
RUNS=${RUNS:-3}
mkdir -p "$WORK/out"
source "$REPO/crates/salvq-wasm/page_setup.sh"
page_setup "$WORK/www"
cp "$REPO/tools/viewer_check/index.html" "$WORK/www/sog.html"
cp "$REPO/tools/viewer_check/throttled_server.py" "$WORK/www/"
# Served gzipped, as a web server configured for wasm sends it; a .sog (webp images in a
# zip) and a .salvq do not shrink further.
gzip -9 -k -f "$WORK/www/pkg/salvq_wasm_bg.wasm"

name=$(basename "$SCENE" .ply)
if [ -n "${STREAM:-}" ]; then
  cp "$STREAM" "$WORK/www/data/scene.salvq"
else
  start=$(date +%s)
  "$SALVQ" encode "$SCENE" -o "$WORK/www/data/scene.salvq" --quiet -f
  echo "salvq encode $name.ply (defaults): $(( $(date +%s) - start )) s"
fi
if [ -n "${SOG:-}" ]; then
  cp "$SOG" "$WORK/www/data/scene.sog"
else
  st=${SPLAT_TRANSFORM:-}
  if [ -z "$st" ]; then
    npm install --prefix "$WORK/st" --no-audit --no-fund --loglevel=error \
      @playcanvas/splat-transform@2.7.1 > /dev/null
    st=$WORK/st/node_modules/.bin/splat-transform
  fi
  # -g cpu: SH bands are clustered on the CPU (no GPU device here).
  "$st" -w -g cpu "$SCENE" "$WORK/www/data/scene.sog" > "$WORK/out/splat_transform.log" 2>&1 \
    || { cat "$WORK/out/splat_transform.log"; exit 1; }
fi
"$SALVQ" info "$WORK/www/data/scene.salvq" > "$WORK/out/info.txt"
cam=$(python3 "$WORK/www/ring_camera.py" "$SCENE" 2)

if (echo > "/dev/tcp/127.0.0.1/$PORT") 2> /dev/null; then
  echo "port $PORT is already in use (PORT=... picks another)"; exit 1
fi
slow=data/,pkg/
if [ -n "${WASM_CACHED:-}" ]; then slow=data/; fi
python3 "$WORK/www/throttled_server.py" "$WORK/www" "$PORT" --rate "${MBIT}e6" --latency "$LATENCY" \
  --slow "$slow" > "$WORK/out/http.log" 2>&1 &
server=$!
trap 'kill $server 2> /dev/null || true' EXIT
sleep 1
base="http://127.0.0.1:$PORT"
echo "-- $RUNS loads of each page at $MBIT Mbit/s, $LATENCY ms (headless Chromium, PlayCanvas engine)"
for i in $(seq 1 "$RUNS"); do
  for kind in salvq sog; do
    if [ "$kind" = salvq ]; then
      url="$base/index.html?stream=data/scene.salvq&bg=0,0,0&ui=0&$cam"
    else
      url="$base/sog.html?ply=data/scene.sog&bg=0,0,0&$cam"
    fi
    (cd "$WORK/www" && WIDTH=512 HEIGHT=384 node shoot.mjs "$url" "$WORK/out/${kind}_$i.png" 500) \
      | grep -v 'GL Driver Message' > "$WORK/out/${kind}_$i.log" || { cat "$WORK/out/${kind}_$i.log"; exit 1; }
  done
done
python3 - "$WORK/out" "$RUNS" "$(stat -c %s "$WORK/www/data/scene.salvq")" \
  "$(stat -c %s "$WORK/www/data/scene.sog")" "$(stat -c %s "$WORK/www/pkg/salvq_wasm_bg.wasm.gz")" \
  "$name" "$MBIT" "$LATENCY" "${WASM_CACHED:-}" <<'PY'
import json, statistics, sys
out, runs, salvq_bytes, sog_bytes, wasm, name, mbit, latency, cached = sys.argv[1:]
runs, salvq_bytes, sog_bytes, wasm = int(runs), int(salvq_bytes), int(sog_bytes), int(wasm)
result = lambda kind, i: json.loads(open(f"{out}/{kind}_{i}.log").read().split('RESULT ', 1)[1].splitlines()[0])
for kind in ('salvq', 'sog'):
    for i in range(1, runs + 1):
        errors = [l for l in open(f"{out}/{kind}_{i}.log") if l.startswith('[pageerror]')]
        if errors:
            sys.exit(f"{kind} run {i}: {errors[0].strip()}")
salvq = [result('salvq', i) for i in range(1, runs + 1)]
sog = [result('sog', i) for i in range(1, runs + 1)]
med = lambda xs: statistics.median(xs)
rows = []
def row(what, entries, total):
    ms = med([e['ms'] for e in entries])
    b = med([e['received'] for e in entries])
    rows.append((what, b, b / total, ms))
total = salvq[0]['gaussians']
for r in salvq + sog:
    if r['numSplats'] != total:
        sys.exit(f"a run drew {r['numSplats']} of {total} Gaussians")
levels = [r['drawn'][-1]['refinements'] for r in salvq]
if min(levels) == 0:
    sys.exit("the salvq file is not progressive: nothing was refined")
row('salvq: first tiles drawn', [r['drawn'][0] for r in salvq], salvq_bytes)
whole = [next(e for e in r['drawn'] if e['gaussians'] == total) for r in salvq]
row('salvq: whole scene first drawn', whole, salvq_bytes)
if any(r['drawn'][-1]['received'] != salvq_bytes for r in salvq):
    sys.exit("the last drawing was not of the whole file")
row('salvq: finest rate drawn', [r['drawn'][-1] for r in salvq], salvq_bytes)
sog_ready = [{'ms': r['loadMs']['ready'], 'received': sog_bytes} for r in sog]
sog_first = [{'ms': r['loadMs']['firstFrame'], 'received': sog_bytes} for r in sog]
row('SOG: asset ready (whole file, images decoded)', sog_ready, sog_bytes)
row('SOG: first frame', sog_first, sog_bytes)
print(f"{name}: {total:,} Gaussians; salvq file {salvq_bytes:,} bytes (drawn refined in place "
      f"{min(levels)} to {max(levels)} times: each drawing takes what arrived) and the wasm package, "
      f"{wasm:,} bytes gzipped{' (cached: not on the link)' if cached else ''}; SOG {sog_bytes:,} bytes; {mbit} Mbit/s, "
      f"{latency} ms; medians of {runs}")
print(f"| {'what':<46} | {'bytes':>11} | {'of its file':>11} | {'ms':>7} |")
print(f"|{'-' * 48}|{'-' * 13}:|{'-' * 13}:|{'-' * 9}:|")
for what, b, frac, ms in rows:
    print(f"| {what:<46} | {b:>11,.0f} | {100 * frac:>10.1f}% | {ms:>7.0f} |")
w = med([e['ms'] for e in whole]); s = med([e['ms'] for e in sog_first])
print(f"salvq's whole scene first drawn / SOG's first frame: {w / s:.2f} of the time, "
      f"{med([e['received'] for e in whole]) / sog_bytes:.2f} of the bytes")
if med([e['received'] for e in whole]) >= salvq_bytes:
    sys.exit("the whole scene was first drawn only when the file was complete")
PY
echo "files in $WORK/out"
