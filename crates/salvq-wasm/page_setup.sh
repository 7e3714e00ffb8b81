# Sourced by browser_test.sh and first_frame_test.sh: `page_setup DIR` builds the wasm-bindgen
# package into DIR/pkg and puts the viewer page (www/), the browser-driving scripts of
# tools/viewer_check and their pinned npm packages (PlayCanvas engine, playwright-core) in DIR,
# with an empty DIR/data for the scene files. Needs REPO and TARGET set.
page_setup() {
  local dir=$1
  mkdir -p "$dir/data"
  echo "-- the package: cargo build --target wasm32-unknown-unknown, then wasm-bindgen --target web"
  (cd "$REPO" && cargo build -q --release -p salvq-wasm --target wasm32-unknown-unknown)
  wasm-bindgen --target web --out-dir "$dir/pkg" "$TARGET/wasm32-unknown-unknown/release/salvq_wasm.wasm"
  cp "$REPO"/crates/salvq-wasm/www/{index.html,worker.js,part_worker.js} "$dir/"
  cp "$REPO"/tools/viewer_check/{package.json,package-lock.json,shoot.mjs,compare.py,ring_camera.py} "$dir/"
  (cd "$dir" && npm ci --no-audit --no-fund --loglevel=error > /dev/null)
}
