// Decodes a .salvq stream with the salvq-wasm package built for Node
// (`wasm-bindgen --target nodejs`) and measures time and memory: what a page's Web Worker
// would meet on the same V8 engine with the same wasm32 limits (a 4 GiB linear memory at most).
//
//   node big_decode.mjs PKG_DIR STREAM.salvq [CHUNK_BYTES] [--stream] [--no-arrays]
//
// Whole mode (default): decode(bytes) once, then each array getter once (what a page reads:
//   every getter copies its array out of wasm into a fresh JS typed array), then free().
// --stream: a Stream fed CHUNK_BYTES (default 1 MiB) at a time, take() after each feed and
//   finish() at the end, each batch's arrays read and dropped (as www/worker.js posts them),
//   peaks sampled after every feed.
// --no-arrays: skip reading the arrays (decode alone).
// --trace: (stream) a line to stderr after each feed: bytes in, Gaussians out, wasm memory, rss.
//
// Prints one line to grep:
//   mode=whole gaussians=N ms=T wasm_memory_bytes=M rss_bytes=R ...
//   mode=stream gaussians=N ms=T wasm_memory_bytes=M rss_bytes=R ...
// or `mode=... failed=<message>` and exits 1. A wasm linear memory only grows, so its size
// after a step is the peak of its memory up to then.
import { createRequire } from 'node:module';
import { readFileSync } from 'node:fs';
import { resolve } from 'node:path';

const args = process.argv.slice(2);
const flags = new Set(args.filter((a) => a.startsWith('--')));
const [pkgDir, streamPath, chunkArg] = args.filter((a) => !a.startsWith('--'));
if (!pkgDir || !streamPath) {
  console.error('usage: node big_decode.mjs PKG_DIR STREAM.salvq [CHUNK_BYTES] [--stream] [--no-arrays]');
  process.exit(2);
}
const mode = flags.has('--stream') ? 'stream' : 'whole';
const readArrays = !flags.has('--no-arrays');
const trace = flags.has('--trace');
const chunk = chunkArg ? Number(chunkArg) : 1 << 20;

const require = createRequire(import.meta.url);
// The nodejs glue of wasm-bindgen 0.2.130 keeps its instance to itself (`let wasm =
// wasmInstance.exports`, nothing exported): catch it as the glue makes it, for its `memory`.
let instance = null;
const Instance = WebAssembly.Instance;
WebAssembly.Instance = class extends Instance {
  constructor(...a) {
    super(...a);
    instance = this;
  }
};
let pkg;
try {
  pkg = require(resolve(pkgDir, 'salvq_wasm.js'));
} finally {
  WebAssembly.Instance = Instance;
}
const memory = instance?.exports.memory ?? pkg.__wasm?.memory;
if (!(memory instanceof WebAssembly.Memory)) {
  console.log(`mode=${mode} failed=no wasm memory export in ${pkgDir}/salvq_wasm.js`);
  process.exit(1);
}
const wasmBytes = () => memory.buffer.byteLength;
const mib = (n) => (n / 2 ** 20).toFixed(1);

const GETTERS = ['positions', 'logScales', 'rotations', 'opacityLogits', 'shDc', 'shRest'];
// Reads every array of a batch as a page does; returns the bytes of JS typed arrays made.
const read = (b) => GETTERS.reduce((n, g) => n + b[g].byteLength, 0);

const bytes = readFileSync(streamPath);
const wasmStart = wasmBytes();
let peakRss = process.memoryUsage().rss;
let peakWasm = wasmStart;
const sample = () => {
  const m = process.memoryUsage();
  peakRss = Math.max(peakRss, m.rss);
  peakWasm = Math.max(peakWasm, wasmBytes());
  return m;
};

// Where a failure happened (the stream mode's step), for the failed line.
let where = '';
function fail(e) {
  const msg = `${e?.name ?? 'Error'}: ${e?.message ?? e}`.replace(/\s+/g, ' ');
  console.log(`mode=${mode} failed=${msg}${where} wasm_memory_bytes=${wasmBytes()} rss_bytes=${process.memoryUsage().rss}`);
  process.exit(1);
}

function whole() {
  const t0 = performance.now();
  let batch;
  try {
    batch = pkg.decode(bytes, undefined);
  } catch (e) {
    fail(e);
  }
  const ms = performance.now() - t0;
  const m = sample();
  const wasmDecoded = wasmBytes();
  const gaussians = batch.count;
  let line = `mode=whole gaussians=${gaussians} sh_degree=${batch.shDegree} stream_bytes=${bytes.length}` +
    ` ms=${ms.toFixed(0)} wasm_memory_bytes=${wasmDecoded} rss_bytes=${m.rss} array_buffers_bytes=${m.arrayBuffers}`;
  if (readArrays) {
    const t1 = performance.now();
    let js;
    try {
      js = read(batch);
    } catch (e) {
      fail(e);
    }
    const a = sample();
    line += ` arrays_ms=${(performance.now() - t1).toFixed(0)} arrays_bytes=${js}` +
      ` wasm_memory_after_arrays_bytes=${wasmBytes()} rss_after_arrays_bytes=${a.rss}` +
      ` array_buffers_after_arrays_bytes=${a.arrayBuffers}`;
  }
  batch.free?.();
  console.log(line + ` wasm_memory_start_bytes=${wasmStart} heap_used_bytes=${process.memoryUsage().heapUsed}`);
  console.error(`whole: ${gaussians} Gaussians in ${ms.toFixed(0)} ms; wasm memory ${mib(wasmStart)} -> ${mib(wasmBytes())} MiB;` +
    ` rss peak ${mib(peakRss)} MiB`);
}

function stream() {
  let decoder;
  let gaussians = 0, batches = 0, replaced = 0, feeds = 0, jsBytes = 0, firstMs = null;
  const take = (b) => {
    if (b.replaces) {
      replaced++;
      gaussians = 0;
    }
    gaussians += b.count;
    if (b.count > 0) batches++;
    if (readArrays) jsBytes += read(b);
    b.free?.();
  };
  const t0 = performance.now();
  try {
    decoder = new pkg.Stream(undefined);
    for (let at = 0; at < bytes.length; at += chunk) {
      const state = () => ` feeds=${feeds} received=${at} gaussians=${gaussians} replaced=${replaced}` +
        ` ms=${(performance.now() - t0).toFixed(0)} peak_wasm_memory_bytes=${peakWasm}`;
      where = ` at=feed${state()}`;
      decoder.feed(bytes.subarray(at, Math.min(bytes.length, at + chunk)));
      feeds++;
      where = ` at=take${state()}`;
      take(decoder.take());
      if (firstMs === null && gaussians > 0) firstMs = performance.now() - t0;
      const m = sample();
      if (trace) {
        console.error(`feed ${feeds} received=${decoder.received()} gaussians=${gaussians} replaced=${replaced}` +
          ` ms=${(performance.now() - t0).toFixed(0)} wasm_memory_bytes=${wasmBytes()} rss_bytes=${m.rss}`);
      }
    }
    where = ` at=finish feeds=${feeds} gaussians=${gaussians} replaced=${replaced} peak_wasm_memory_bytes=${peakWasm}`;
    take(decoder.finish());
    sample();
    decoder.free?.();
  } catch (e) {
    fail(e);
  }
  where = '';
  const ms = performance.now() - t0;
  const m = process.memoryUsage();
  console.log(`mode=stream gaussians=${gaussians} stream_bytes=${bytes.length} chunk_bytes=${chunk} feeds=${feeds}` +
    ` batches=${batches} replaced=${replaced} ms=${ms.toFixed(0)} first_gaussians_ms=${firstMs?.toFixed(0)}` +
    ` wasm_memory_bytes=${peakWasm} rss_bytes=${peakRss} array_buffers_bytes=${m.arrayBuffers}` +
    ` arrays_bytes=${jsBytes} wasm_memory_start_bytes=${wasmStart}`);
  console.error(`stream: ${gaussians} Gaussians in ${ms.toFixed(0)} ms (${feeds} feeds of ${chunk} bytes);` +
    ` wasm memory ${mib(wasmStart)} -> peak ${mib(peakWasm)} MiB; rss peak ${mib(peakRss)} MiB`);
}

try {
  if (mode === 'stream') stream();
  else whole();
} catch (e) {
  fail(e);
}
