// Times salvq-wasm's `decode(bytes, rate)` in Node (V8 runs the same WebAssembly a Chromium
// page does) for `cargo bench --bench decode_speed`, which writes this file next to the
// package that `wasm-bindgen --target nodejs` made.
// usage: node decode_time.cjs PKG_JS STREAM RUNS DUMP
//   prints one line `RESULT {"ms":[...],"count":N}` (each run's milliseconds, the first
//   included) and writes the last decode's arrays, float32 little-endian, to DUMP in the order
//   positions, logScales, rotations, opacityLogits, shDc, shRest (the bench compares them with
//   the native decode).
'use strict';
const fs = require('fs');
const [pkgJs, streamPath, runsArg, dumpPath] = process.argv.slice(2);
const { decode } = require(pkgJs);
const bytes = new Uint8Array(fs.readFileSync(streamPath));
const runs = Number(runsArg);
const ms = [];
let last = null;
for (let i = 0; i < runs; i++) {
  if (last) last.free();
  const t = performance.now();
  last = decode(bytes, undefined);
  ms.push(performance.now() - t);
}
const parts = [last.positions, last.logScales, last.rotations, last.opacityLogits, last.shDc, last.shRest];
fs.writeFileSync(dumpPath, Buffer.concat(parts.map((a) => Buffer.from(a.buffer, a.byteOffset, a.byteLength))));
console.log('RESULT ' + JSON.stringify({ ms, count: last.count }));
