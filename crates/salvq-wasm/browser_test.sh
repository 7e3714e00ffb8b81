#!/usr/bin/env bash
# The WebAssembly decoder in a real browser: builds the wasm-bindgen
# package, encodes a real scene, serves crates/salvq-wasm/www on localhost, loads it in
# headless Chromium (the page fetches the stream, decodes it in a Web Worker as the bytes
# arrive, and draws it with the PlayCanvas engine), screenshots it, and compares the
# screenshot with `salvq render` of the same stream from the same camera. Fails unless
#  - the wasm file is within its size budget (WASM_BUDGET below, docs/web/README.md);
#  - the picture matches (and matches the wrong camera clearly worse), from a camera given by
#    URL (cam=...) and from the page's own first view (no cam=: framed on the scene's bounds,
#    ring camera 0 of Annex C.2, so `salvq render --view 0`);
#  - the whole decode in the browser (median of 5, drawing paused) takes at most 2.0 times the
#    native single-thread decode of the same stream, where the native decode takes 50 ms or
#    more (shorter ones are printed, not asserted: a 10 ms decode on a shared machine is noise);
#  - the stream's tiles were drawn before it was complete, and 2 Web Workers decoding a part
#    each (decodePart, spec §10.3.2) hold every tile once and every Gaussian.
# usage: crates/salvq-wasm/browser_test.sh [SCENE.ply]   (default ../shared/data/playbot.ply)
#   PSNR=40 (the encoder's targets; rate 0, the first, is drawn), TILE_ANCHORS=0 (the encoder's
#   default tiles; e.g. 1024 cuts a small scene into more), VIEW=2 (the ring camera given by URL), WORK=dir keeps the files,
#   STREAM=file.salvq draws that stream (encoded from SCENE earlier) instead of encoding SCENE.
#   Needs $SALVQ (default: target/release/salvq, under $CARGO_TARGET_DIR when set),
#   wasm-bindgen 0.2.130 (install_wasm_bindgen_cli.sh), node >= 18 with npm, /usr/bin/chromium
#   (or $CHROMIUM), python3 with numpy and pillow.
set -euo pipefail
REPO=$(cd "$(dirname "$0")/../.." && pwd)
TARGET=${CARGO_TARGET_DIR:-$REPO/target}
case "$TARGET" in /*) ;; *) TARGET=$REPO/$TARGET ;; esac
SALVQ=${SALVQ:-$TARGET/release/salvq}
SCENE=${1:-$REPO/../shared/data/playbot.ply}
WORK=${WORK:-$(mktemp -d)}
PORT=${PORT:-8766}
VIEW=${VIEW:-2}
PSNR=${PSNR:-40}
TILE_ANCHORS=${TILE_ANCHORS:-0}
# The wasm file's size budget in bytes: 583,503 measured on 2026-12-02 (rustc 1.95, simd128),
# plus about 10 %. A change that needs more raises it here and in docs/web/README.md, saying
# what the bytes bought.
WASM_BUDGET=640000
mkdir -p "$WORK/www/data" "$WORK/out"
# Runs a command with its output kept in a log, shown if it fails.
quiet() { "$@" > "$WORK/out/last.log" 2>&1 || { cat "$WORK/out/last.log"; exit 1; }; }

source "$REPO/crates/salvq-wasm/page_setup.sh"
page_setup "$WORK/www"
raw=$(stat -c %s "$WORK/www/pkg/salvq_wasm_bg.wasm")
gz=$(gzip -9 -c "$WORK/www/pkg/salvq_wasm_bg.wasm" | wc -c)
echo "wasm: $raw bytes ($gz gzipped), budget $WASM_BUDGET bytes"
if [ "$raw" -gt "$WASM_BUDGET" ]; then
  echo "the wasm file is over its budget of $WASM_BUDGET bytes (docs/web/README.md)"; exit 1
fi

echo "-- the stream: $(basename "$SCENE") at --psnr $PSNR; the reference renders and camera"
tiles=()
if [ "$TILE_ANCHORS" != 0 ]; then tiles=(--tile-anchors "$TILE_ANCHORS"); fi
start=$(date +%s)
if [ -n "${STREAM:-}" ]; then
  cp "$STREAM" "$WORK/www/data/scene.salvq"
  echo "not encoded: STREAM=$STREAM, $(stat -c %s "$WORK/www/data/scene.salvq") bytes"
else
  quiet "$SALVQ" encode "$SCENE" --psnr "$PSNR" ${tiles[@]+"${tiles[@]}"} -o "$WORK/www/data/scene.salvq"
  echo "encoded in $(( $(date +%s) - start )) s: $(stat -c %s "$WORK/www/data/scene.salvq") bytes"
fi
quiet "$SALVQ" decode "$WORK/www/data/scene.salvq" --rate 0 -o "$WORK/out/scene.ply"
wrong=$(( (VIEW + 4) % 8 ))
for v in "$VIEW" "$wrong" 0 4; do
  quiet "$SALVQ" render "$WORK/www/data/scene.salvq" --rate 0 --view "$v" --width 512 --height 384 \
    -o "$WORK/out/salvq_render_$v.png"
done
cam=$(python3 "$WORK/www/ring_camera.py" "$WORK/out/scene.ply" "$VIEW")

echo "-- native decode of the same stream, in process, one thread (cargo bench --bench first_tile)"
(cd "$REPO" && SALVQ_BENCH_STREAM="$WORK/www/data/scene.salvq" cargo bench -q --bench first_tile) \
  | tee "$WORK/out/native.txt"

if (echo > "/dev/tcp/127.0.0.1/$PORT") 2> /dev/null; then
  echo "port $PORT is already in use (PORT=... picks another)"; exit 1
fi
(cd "$WORK/www" && exec python3 -m http.server "$PORT" --bind 127.0.0.1 > "$WORK/out/http.log" 2>&1) &
server=$!
trap 'kill $server 2> /dev/null || true' EXIT
sleep 1
page="http://127.0.0.1:$PORT/index.html?stream=data/scene.salvq&rate=0&bg=0,0,0&ui=0"
echo "-- the page in headless Chromium: ring camera $VIEW by URL; 5 whole decodes timed, 1 and 2 part workers"
(cd "$WORK/www" && WIDTH=512 HEIGHT=384 node shoot.mjs "$page&slice=8192&time=5&parts=2&$cam" "$WORK/out/browser.png") \
  | grep -v 'GL Driver Message' > "$WORK/out/browser.log" || { cat "$WORK/out/browser.log"; exit 1; }
grep -E '^(BROWSER|\[pageerror\])' "$WORK/out/browser.log" || true
echo "-- the page's own first view (no cam=)"
(cd "$WORK/www" && WIDTH=512 HEIGHT=384 node shoot.mjs "$page" "$WORK/out/browser_default.png") \
  | grep -v 'GL Driver Message' > "$WORK/out/browser_default.log" || { cat "$WORK/out/browser_default.log"; exit 1; }
cmp=$WORK/www/compare.py
{
  python3 "$cmp" "$WORK/out/browser.png" "$WORK/out/salvq_render_$VIEW.png"
  python3 "$cmp" "$WORK/out/browser.png" "$WORK/out/salvq_render_$wrong.png"
  python3 "$cmp" "$WORK/out/browser_default.png" "$WORK/out/salvq_render_0.png"
  python3 "$cmp" "$WORK/out/browser_default.png" "$WORK/out/salvq_render_4.png"
} > "$WORK/out/compare.txt"
python3 - "$WORK/out/compare.txt" "$WORK/out/browser.log" "$WORK/out/native.txt" "$raw" "$gz" "$WASM_BUDGET" <<'PY'
import json, re, statistics, sys
print(f"wasm: {int(sys.argv[4]):,} bytes ({int(sys.argv[5]):,} gzipped), within its budget of {int(sys.argv[6]):,}")
right, wrong, first, first_wrong = [float(x) for x in re.findall(r'PSNR ([\d.]+) dB', open(sys.argv[1]).read())]
result = json.loads(open(sys.argv[2]).read().split('RESULT ', 1)[1].splitlines()[0])
native = float(re.search(r'whole decode: ([\d.]+) s on 1 thread', open(sys.argv[3]).read()).group(1))
w = result['worker']
print(f"browser screenshot vs salvq render: {right:.2f} dB (same camera), {wrong:.2f} dB (opposite camera)")
print(f"the page's first view vs salvq render --view 0: {first:.2f} dB (view 4: {first_wrong:.2f} dB)")
print(f"streamed: {result['gaussians']} Gaussians in {result['batches']} batches; first tiles after "
      f"{w['firstTile']['bytes']} of {w['received']} bytes ({w['firstTile']['ms']:.0f} ms after the page asked)")
runs = w['wholeDecodeMs']
browser = statistics.median(runs)
ratio = browser / (1000 * native)
print(f"whole decode in the browser (median of {len(runs)}, drawing paused): {browser:.1f} ms "
      f"(runs {', '.join(f'{x:.1f}' for x in runs)}); native, one thread (best of 3): "
      f"{1000 * native:.1f} ms; browser / native {ratio:.2f}")
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
if first < 22 or first < first_wrong + 3:
    sys.exit("the page's first view is not ring camera 0 (salvq render --view 0)")
if result['batches'] < 2 or w['firstTile']['bytes'] >= w['received']:
    sys.exit("the page did not draw tiles before the stream was complete")
if native >= 0.05 and ratio > 2.0:
    sys.exit(f"the browser's decode takes {ratio:.2f} times the native one: the goal is 2.0 at most")
if native < 0.05:
    print("browser / native not asserted: the native decode is under 50 ms")
PY
echo "files in $WORK/out"
