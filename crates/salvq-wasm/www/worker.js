// Decodes a .salvq stream in a Web Worker as its bytes arrive (salvq-wasm's Stream) and posts
// the Gaussians of each batch of completed tiles to the page as transferable typed arrays.
// Messages from the page:
//   { kind: 'stream', url, rate, slice }  decode the stream at `url` as it arrives: 'tiles'
//                                         messages (a batch with `replaces` holds every
//                                         Gaussian at a finer rate: a progressive stream's
//                                         refinement), then 'done' (or 'error')
//   { kind: 'time', url, rate, runs }     decode the stream whole `runs` times (decode()):
//                                         'timed' with each run's milliseconds, sorted
import init, { Stream, decode } from './pkg/salvq_wasm.js';

const arrays = (b) => ({
  count: b.count, tiles: b.tiles, shDegree: b.shDegree, replaces: b.replaces,
  positions: b.positions, logScales: b.logScales, rotations: b.rotations,
  opacityLogits: b.opacityLogits, shDc: b.shDc, shRest: b.shRest,
});
const transfer = (a) => [a.positions, a.logScales, a.rotations, a.opacityLogits, a.shDc, a.shRest].map((x) => x.buffer);
let ready = null;

async function stream({ url, rate, slice }) {
  const t0 = performance.now();
  ready ??= init();
  await ready;
  const tInit = performance.now();
  const response = await fetch(url);
  if (!response.ok) throw new Error(`fetch ${url}: ${response.status}`);
  const reader = response.body.getReader();
  const decoder = new Stream(rate ?? undefined);
  let decodeMs = 0, received = 0, firstTile = null, pieces = 0;
  const post = (b, kind) => {
    const a = arrays(b);
    b.free();
    if (a.count === 0 && kind === 'tiles') return;
    if (firstTile === null && a.count > 0) firstTile = { ms: performance.now() - t0, bytes: received };
    self.postMessage({ kind, batch: a, received }, transfer(a));
  };
  for (;;) {
    const { done, value } = await reader.read();
    if (done) break;
    // `slice` feeds what arrived in smaller pieces, as a slow link would deliver it.
    const step = slice > 0 ? slice : value.length;
    for (let at = 0; at < value.length; at += step) {
      const piece = value.subarray(at, Math.min(value.length, at + step));
      received += piece.length;
      pieces++;
      const t = performance.now();
      decoder.feed(piece);
      const batch = decoder.take();
      decodeMs += performance.now() - t;
      post(batch, 'tiles');
    }
  }
  const t = performance.now();
  const last = decoder.finish();
  decodeMs += performance.now() - t;
  post(last, 'tiles');
  decoder.free();
  self.postMessage({
    kind: 'done', received, pieces, decodeMs, firstTile,
    initMs: tInit - t0, totalMs: performance.now() - t0, wholeDecodeMs: [],
  });
}

// The same bytes decoded whole: the decode time without the network in between (what the
// native decoder's whole-buffer decode is compared with).
async function time({ url, rate, runs }) {
  ready ??= init();
  await ready;
  const bytes = new Uint8Array(await (await fetch(url)).arrayBuffer());
  const ms = [];
  for (let i = 0; i < runs; i++) {
    const s = performance.now();
    decode(bytes, rate ?? undefined).free();
    ms.push(performance.now() - s);
  }
  ms.sort((x, y) => x - y);
  self.postMessage({ kind: 'timed', wholeDecodeMs: ms });
}

self.onmessage = async (ev) => {
  try {
    if (ev.data.kind === 'time') await time(ev.data);
    else await stream(ev.data);
  } catch (e) {
    self.postMessage({ kind: 'error', error: String(e && e.message || e) });
  }
};
