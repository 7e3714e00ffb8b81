#!/usr/bin/env bash
# The WebAssembly decoder in a real browser (issue 20): builds the wasm-bindgen package, encodes
# a real scene, serves crates/salvq-wasm/www on localhost, loads it in headless Chromium
# (the page fetches the stream, decodes it in a Web Worker as the bytes arrive, and draws it
# with the PlayCanvas engine), screenshots it, and compares the screenshot with
# `salvq render` of the same stream from the same camera. Fails unless the picture matches
# (and matches the wrong camera clearly worse). The page also times the whole stream decoded
# by 1 and by 2 Web Workers, each its part of the tiles (decodePart, spec §10.3.2); fails
# unless the two parts hold every tile once and every Gaussian.
# usage: crates/salvq-wasm/browser_test.sh [SCENE.ply]   (default ../shared/data/fruit_drops.ply)
#   needs target/release/salvq, wasm-bindgen (0.2.130, as the crate pins), node >= 18 with npm,
#   /usr/bin/chromium (or $CHROMIUM), python3 with numpy and pillow. WORK=dir keeps the files.
set -euo pipefail
REPO=$(cd "$(dirname "$0")/../.." && pwd)
SALVQ=${SALVQ:-$REPO/target/release/salvq}
SCENE=${1:-$REPO/../shared/data/fruit_drops.ply}
WORK=${WORK:-$(mktemp -d)}
PORT=${PORT:-8766}
VIEW=${VIEW:-2}
mkdir -p "$WORK/www/data" "$WORK/out"

echo "-- the package: cargo build --target wasm32-unknown-unknown, then wasm-bindgen --target web"
(cd "$REPO" && cargo build -q --release -p salvq-wasm --target wasm32-unknown-unknown)
wasm=$REPO/target/wasm32-unknown-unknown/release/salvq_wasm.wasm
wasm-bindgen --target web --out-dir "$WORK/www/pkg" "$wasm"
raw=$(stat -c %s "$WORK/www/pkg/salvq_wasm_bg.wasm")
gz=$(gzip -9 -c "$WORK/www/pkg/salvq_wasm_bg.wasm" | wc -c)
echo "wasm: $raw bytes, $gz gzipped"

cp "$REPO"/crates/salvq-wasm/www/{index.html,worker.js,part_worker.js} "$WORK/www/"
cp "$REPO"/tools/viewer_check/{package.json,package-lock.json,shoot.mjs,compare.py,ring_camera.py} "$WORK/www/"
(cd "$WORK/www" && npm ci --no-audit --no-fund --loglevel=error > /dev/null)

echo "-- the stream: $(basename "$SCENE") at two rates; the reference render and camera"
"$SALVQ" encode "$SCENE" --psnr 50,40 --tile-anchors 1024 -o "$WORK/www/data/scene.salvq" --quiet
"$SALVQ" decode "$WORK/www/data/scene.salvq" --rate 0 -o "$WORK/out/scene.ply" > /dev/null
"$SALVQ" render "$WORK/www/data/scene.salvq" --rate 0 --view "$VIEW" --width 512 --height 384 -o "$WORK/out/salvq_render.png"
wrong=$(( (VIEW + 4) % 8 ))
"$SALVQ" render "$WORK/www/data/scene.salvq" --rate 0 --view "$wrong" --width 512 --height 384 -o "$WORK/out/salvq_render_wrong.png"
cam=$(python3 "$WORK/www/ring_camera.py" "$WORK/out/scene.ply" "$VIEW")

echo "-- native decode of the same stream, in process (cargo bench --bench first_tile)"
(cd "$REPO" && SALVQ_BENCH_STREAM="$WORK/www/data/scene.salvq" cargo bench -q --bench first_tile) \
  | tee "$WORK/out/native.txt"

if (echo > "/dev/tcp/127.0.0.1/$PORT") 2> /dev/null; then
  echo "port $PORT is already in use (PORT=... picks another)"; exit 1
fi
(cd "$WORK/www" && exec python3 -m http.server "$PORT" --bind 127.0.0.1 > "$WORK/out/http.log" 2>&1) &
server=$!
trap 'kill $server 2> /dev/null || true' EXIT
sleep 1
echo "-- the page in headless Chromium"
(cd "$WORK/www" && WIDTH=512 HEIGHT=384 node shoot.mjs \
  "http://127.0.0.1:$PORT/index.html?stream=data/scene.salvq&rate=0&slice=8192&parts=2&bg=0,0,0&$cam" "$WORK/out/browser.png") \
  | grep -v 'GL Driver Message' | tee "$WORK/out/browser.log"
python3 "$WORK/www/compare.py" "$WORK/out/browser.png" "$WORK/out/salvq_render.png" | tee "$WORK/out/compare.txt"
python3 "$WORK/www/compare.py" "$WORK/out/browser.png" "$WORK/out/salvq_render_wrong.png" | tee -a "$WORK/out/compare.txt"
python3 - "$WORK/out/compare.txt" "$WORK/out/browser.log" "$WORK/out/native.txt" <<'PY'
import json, re, statistics, sys
right, wrong = [float(x) for x in re.findall(r'PSNR ([\d.]+) dB', open(sys.argv[1]).read())]
result = json.loads(open(sys.argv[2]).read().split('RESULT ', 1)[1].splitlines()[0])
native = float(re.search(r'whole decode: ([\d.]+) s on 1 thread', open(sys.argv[3]).read()).group(1))
w = result['worker']
print(f"browser screenshot vs salvq render: {right:.2f} dB (same camera), {wrong:.2f} dB (opposite camera)")
print(f"streamed: {result['gaussians']} Gaussians in {result['batches']} batches; first tiles after "
      f"{w['firstTile']['bytes']} of {w['received']} bytes ({w['firstTile']['ms']:.0f} ms after the page asked)")
browser = statistics.median(w['wholeDecodeMs'])
print(f"whole decode in the browser (median of 5): {browser:.1f} ms; native, one thread (best of 3): "
      f"{1000 * native:.1f} ms; browser / native {browser / (1000 * native):.2f}")
p = result['parts']
one, two = statistics.median(p['oneWorkerMs']), statistics.median(p['nWorkersMs'])
print(f"whole decode on Web Workers, each its part of the tiles (decodePart, median of 5): 1 worker "
      f"{one:.1f} ms, {p['workers']} workers {two:.1f} ms ({p['workers']} / 1: {two / one:.2f}; tiles "
      f"{[len(t) for t in p['tiles']]}, Gaussians {p['counts']})")
tiles = sorted(t for part in p['tiles'] for t in part)
if tiles != list(range(len(tiles))) or sum(p['counts']) != result['gaussians']:
    sys.exit("the parts do not hold every tile once and every Gaussian")
if right < 22 or right < wrong + 5:
    sys.exit("the browser's picture does not match salvq render of the same camera")
if result['batches'] < 2 or w['firstTile']['bytes'] >= w['received']:
    sys.exit("the page did not draw tiles before the stream was complete")
PY
echo "files in $WORK/out"
