// Times salvq-wasm's `decode(bytes, rate)` in Node (V8 runs the same WebAssembly a Chromium
// page does) for `cargo bench --bench decode_speed`, which writes this file next to the
// package that `wasm-bindgen --target nodejs` made.
// usage: node decode_time.cjs PKG_JS STREAM RUNS DUMP [WORKERS]
//   Without WORKERS (or 0): `decode` on the main thread. With WORKERS = W >= 1: W worker
//   threads (started, and their WebAssembly compiled, before the first run), each sent the
//   stream's bytes and decoding its part with `decodePart(bytes, rate, w, W)` (spec §10.3.2);
//   a run is timed from sending the bytes to the last part's arrays arriving, as a viewer
//   would have them.
//   Prints one line `RESULT {"ms":[...],"count":N}` (each run's milliseconds, the first
//   included) and writes the last decode's arrays, float32 little-endian, to DUMP in the order
//   positions, logScales, rotations, opacityLogits, shDc, shRest (the bench compares them with
//   the native decode); the parts' tiles are put back in stream order first.
'use strict';
const fs = require('fs');
const { Worker, isMainThread, parentPort, workerData } = require('worker_threads');

const FIELDS = ['positions', 'logScales', 'rotations', 'opacityLogits', 'shDc', 'shRest'];

if (!isMainThread) {
  // A worker: decode its part of each stream it is sent, hand the arrays back.
  const { decodePart } = require(workerData.pkgJs);
  parentPort.on('message', ({ bytes, part, parts }) => {
    const batch = decodePart(bytes, undefined, part, parts);
    const out = { count: batch.count, tileIndices: batch.tileIndices, tileCounts: batch.tileCounts };
    for (const f of FIELDS) out[f] = batch[f];
    batch.free();
    parentPort.postMessage(out, FIELDS.map((f) => out[f].buffer));
  });
  return;
}

const [pkgJs, streamPath, runsArg, dumpPath, workersArg] = process.argv.slice(2);
const bytes = new Uint8Array(fs.readFileSync(streamPath));
const runs = Number(runsArg);
const workers = Number(workersArg || 0);

// The parts' arrays, tile by tile in stream order: one array per field.
function inStreamOrder(parts) {
  const pieces = [];
  for (const p of parts) {
    let at = 0;
    p.tileIndices.forEach((t, i) => {
      pieces.push({ t, p, at, n: p.tileCounts[i] });
      at += p.tileCounts[i];
    });
    if (at !== p.count) throw new Error(`a part's tiles hold ${at} Gaussians, its arrays ${p.count}`);
  }
  pieces.sort((a, b) => a.t - b.t);
  const total = pieces.reduce((s, x) => s + x.n, 0);
  const out = {};
  for (const f of FIELDS) {
    const width = total === 0 ? 0 : parts.reduce((w, p) => (p.count ? p[f].length / p.count : w), 0);
    const a = new Float32Array(total * width);
    let at = 0;
    for (const x of pieces) {
      a.set(x.p[f].subarray(x.at * width, (x.at + x.n) * width), at);
      at += x.n * width;
    }
    out[f] = a;
  }
  out.count = total;
  return out;
}

function report(ms, last) {
  const arrays = FIELDS.map((f) => last[f]);
  fs.writeFileSync(dumpPath, Buffer.concat(arrays.map((a) => Buffer.from(a.buffer, a.byteOffset, a.byteLength))));
  console.log('RESULT ' + JSON.stringify({ ms, count: last.count }));
}

async function withWorkers() {
  const pool = [];
  for (let w = 0; w < workers; w++) {
    const worker = new Worker(__filename, { workerData: { pkgJs } });
    // Started once the package is loaded: the first message waits for it.
    pool.push(worker);
  }
  const ask = (worker, part) =>
    new Promise((resolve, reject) => {
      worker.once('message', resolve);
      worker.once('error', reject);
      // A copy of the bytes for each worker, as a viewer sending them would make.
      worker.postMessage({ bytes: bytes.slice(), part, parts: workers });
    });
  const ms = [];
  let parts = null;
  for (let i = 0; i < runs; i++) {
    const t = performance.now();
    parts = await Promise.all(pool.map((worker, part) => ask(worker, part)));
    ms.push(performance.now() - t);
  }
  report(ms, inStreamOrder(parts));
  await Promise.all(pool.map((w) => w.terminate()));
}

if (workers > 0) {
  withWorkers().catch((e) => {
    console.error(e);
    process.exit(1);
  });
} else {
  const { decode } = require(pkgJs);
  const ms = [];
  let last = null;
  for (let i = 0; i < runs; i++) {
    if (last) last.free();
    const t = performance.now();
    last = decode(bytes, undefined);
    ms.push(performance.now() - t);
  }
  const out = { count: last.count };
  for (const f of FIELDS) out[f] = last[f];
  report(ms, out);
}
