#!/usr/bin/env bash
# Reproduce docs/renders/viewer_{generated,guitar}.png: export a generated scene with
# salvq, load it (and guitar.ply as a control) in the PlayCanvas engine's gsplat renderer in
# headless Chromium, screenshot ring cameras, and compare with `salvq render` of the same view.
# Runs in a scratch copy ($WORK) so no node_modules or data land in the repository.
# usage: tools/viewer_check/run.sh            (from the repository root; needs target/release/salvq,
#        node >= 18, npm, /usr/bin/chromium, python3 with numpy, safetensors and pillow)
set -euo pipefail
REPO=$(cd "$(dirname "$0")/../.." && pwd)
SALVQ=$REPO/target/release/salvq
WORK=${WORK:-/tmp/viewer_check}
PORT=${PORT:-8765}
GUITAR=${GUITAR:-$REPO/../shared/data/guitar.ply}
mkdir -p "$WORK/data" "$WORK/out"
cp "$REPO"/tools/viewer_check/{index.html,shoot.mjs,ring_camera.py,compare.py,package.json} "$WORK"/
[ -f "$REPO/tools/viewer_check/package-lock.json" ] && cp "$REPO/tools/viewer_check/package-lock.json" "$WORK"/
cd "$WORK"
if [ -f package-lock.json ]; then npm ci --no-audit --no-fund; else npm install --no-audit --no-fund; fi

# salvq output: generated scene -> stream -> exported PLY (ring camera 0); -f: a WORK folder
# kept from an earlier run (WORK=dir) holds these files already.
"$SALVQ" gen --anchors 20000 --seed 1 -o data/g.safetensors -f
"$SALVQ" encode data/g.safetensors -o data/g.salvq -f
"$SALVQ" export-ply data/g.salvq -o data/g.ply -f
"$SALVQ" decode data/g.salvq -o data/g.dec.safetensors -f      # only for the ring camera's bounds
cp "$GUITAR" data/guitar.ply
# reference images from salvq's own CPU rasterizer, same cameras
"$SALVQ" render data/g.salvq --view 0 -o out/salvq_generated_view0.png -f
"$SALVQ" render data/guitar.ply --view 2 -o out/salvq_guitar_view2.png -f

python3 -m http.server "$PORT" --bind 127.0.0.1 >out/http.log 2>&1 &
SERVER=$!
trap 'kill $SERVER' EXIT
sleep 1
GEN_CAM=$(python3 ring_camera.py data/g.dec.safetensors 0)
GUITAR_CAM=$(python3 ring_camera.py data/guitar.ply 2)
WIDTH=512 HEIGHT=384 node shoot.mjs "http://127.0.0.1:$PORT/index.html?ply=data/g.ply&bg=0,0,0&$GEN_CAM" out/viewer_generated.png \
  | grep -v 'GL Driver Message' | tee out/generated.log
WIDTH=512 HEIGHT=384 node shoot.mjs "http://127.0.0.1:$PORT/index.html?ply=data/guitar.ply&bg=0,0,0&$GUITAR_CAM" out/viewer_guitar.png \
  | grep -v 'GL Driver Message' | tee out/guitar.log
python3 compare.py out/viewer_generated.png out/salvq_generated_view0.png
python3 compare.py out/viewer_guitar.png out/salvq_guitar_view2.png
sha256sum data/g.safetensors data/g.salvq data/g.ply data/guitar.ply
echo "screenshots in $WORK/out (copy to docs/renders/ to update)"
