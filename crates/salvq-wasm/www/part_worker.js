// Decodes one part of a .salvq stream's tiles in a Web Worker (salvq-wasm's decodePart, spec
// §10.3.2): the page sends the whole stream to each of n such workers, each with its own part,
// and gets back the Gaussians of that part's tiles as transferable typed arrays.
import init, { decodePart } from './pkg/salvq_wasm.js';

const FIELDS = ['positions', 'logScales', 'rotations', 'opacityLogits', 'shDc', 'shRest'];
let ready = null;

self.onmessage = async (ev) => {
  const { bytes, rate, part, parts } = ev.data;
  try {
    ready ??= init();
    await ready;
    const t = performance.now();
    const b = decodePart(bytes, rate ?? undefined, part, parts);
    const out = { count: b.count, shDegree: b.shDegree, tileIndices: b.tileIndices, tileCounts: b.tileCounts };
    for (const f of FIELDS) out[f] = b[f];
    b.free();
    out.decodeMs = performance.now() - t;
    self.postMessage({ kind: 'part', batch: out }, FIELDS.map((f) => out[f].buffer));
  } catch (e) {
    self.postMessage({ kind: 'error', error: String(e && e.message || e) });
  }
};
