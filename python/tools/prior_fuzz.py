"""Differential fuzzing of the explicit profile's prior (§3.5) and reconstruction (§3.6)
against a reference binary (optional; needs it).

    python3 tools/prior_fuzz.py REF_BINARY VECTORS_DIR [ITERATIONS] [SEED]

Takes an explicit-profile vector, draws a new valid `GLAY` (prediction level, rotation
frequencies, size thresholds, refinement bits, step shifts, scale-index offsets, predict
flags, the `sh_rest` count's tree, scale tables with entries 0 … 127, wide scales included),
new coordinates (small, large, escaped, up to ±2^24), rotation indices and refinements,
re-encodes the layer's `GATT` with `tools/reencode.py` (salvq_py's reading of §3.5), and checks
that the reference decodes it to the same canonical form (both hashes)."""
from __future__ import annotations

import json
import os
import random
import struct
import sys

sys.path.insert(0, os.path.dirname(__file__))
from diff_fuzz import chunks, rebuild, run_mine, run_ref  # noqa: E402
from reencode import encode_gatt  # noqa: E402
from salvq_py import decode_bytes  # noqa: E402
from salvq_py.explicit import glay_length, parse_glay, rest_count_bits  # noqa: E402
from salvq_py.gatt import size_class  # noqa: E402
from salvq_py.tiles import parse_tils  # noqa: E402


def _chunk(data: bytes, tag: str, nth: int):
    hits = [(i, p, n) for i, (p, n, t) in enumerate(chunks(data)) if t == tag.encode()]
    i, p, n = hits[nth]
    return i, data[p + 8:p + 8 + n]


def random_glay(rng: random.Random, h, coord_bits: int, voxel_size: bytes) -> bytes:
    G, D = h.G, h.D
    thr = sorted(rng.randint(-40, 40) for _ in range(3))
    out = bytearray([0, coord_bits]) + voxel_size
    out.append(rng.randint(0, coord_bits))                                   # pred_level
    for _ in range(3):
        out += struct.pack("<H", rng.choice([1, 2, 100, 32768, 40000, 65535, rng.randint(1, 65535)]))
    for t in thr:
        out += struct.pack("<i", t)
    out += bytes(rng.randint(0, min(4, 24 - coord_bits)) for _ in range(4))   # refine
    out += bytes((rng.randint(-16, 16)) & 0xFF for _ in range(4 * (G - 1)))  # shift
    out += bytes((rng.randint(-63, 63)) & 0xFF for _ in range(4 * (G - 1)))  # scale_offset
    out += bytes(rng.randint(0, 1) for _ in range(G))                         # predict
    for _ in range((1 << rest_count_bits(h)) - 1):                            # rest_count_freq (0.13)
        out += struct.pack("<H", rng.choice([1, 32768, 65535, rng.randint(1, 65535)]))
    out += bytes(rng.choice([rng.randint(0, 63), rng.randint(0, 127), rng.randint(56, 127)])
                 for _ in range(8 * D))                                       # scale_table (0.14: 0 … 127)
    assert len(out) == glay_length(h)
    return bytes(out)


def random_coordinate(rng: random.Random) -> int:
    kind = rng.random()
    if kind < 0.6:
        return rng.randint(-6, 6)
    if kind < 0.85:
        return rng.randint(-300, 300)
    if kind < 0.92:
        return rng.randint(-20000, 20000)         # spreads the wide scales (0.14) serve
    if kind < 0.97:
        return rng.randint(-(1 << 20), 1 << 20)
    return rng.choice([1 << 24, -(1 << 24), (1 << 24) - 1])


def trial(ref: str, data: bytes, rate: int, rng: random.Random):
    dec = decode_bytes(data, rate)
    h = dec.head
    nth = h.coded_rates().index(rate)
    gi, glay = _chunk(data, "GLAY", nth)
    old = parse_glay(glay, h)
    new = random_glay(rng, h, old.coord_bits, glay[2:6])
    lay = parse_glay(new, h)
    _, tils = _chunk(data, "TILS", nth)
    tiles = parse_tils(tils, h.N, lay.coord_bits)
    N = h.N
    coords = dec.integers["symbols.coordinates"].copy()
    if rng.random() < 0.7:
        for n in range(N):
            for v in range(h.D):
                if rng.random() < 0.3:
                    coords[n, v] = random_coordinate(rng)
    rot = [rng.randint(0, 3) for _ in range(N)]
    classes = [size_class([int(x) for x in coords[n, 0:3]], lay.size_threshold) for n in range(N)]
    refinement = [[rng.randrange(1 << lay.refine[c]) for _ in range(3)] for c in classes]
    import numpy as np
    gatt = encode_gatt(h, lay, tiles, dec.integers["gaussian.voxel"], coords, np.array(rot),
                       np.array(classes), np.array(refinement))
    out = rebuild(data, gi, new)
    ti, _ = _chunk(out, "GATT", nth)
    return rebuild(out, ti, gatt)


def main():
    ref, vdir = sys.argv[1], sys.argv[2]
    iters = int(sys.argv[3]) if len(sys.argv) > 3 else 50
    rng = random.Random(int(sys.argv[4]) if len(sys.argv) > 4 else 1)
    manifest = json.load(open(os.path.join(vdir, "manifest.json")))
    bases = [(v["file"], d["rate"]) for v in manifest["vectors"]
             if v["kind"] == "valid" and v["name"].startswith("g-") for d in v["decodes"]]
    disagree = 0
    for it in range(iters):
        fname, rate = rng.choice(bases)
        data = trial(ref, open(os.path.join(vdir, fname), "rb").read(), rate, rng)
        r, m = run_ref(ref, data, rate), run_mine(data, rate)
        if r[:2] != m[:2] or m[0] != "ok" and m[1] != "ValueInvalid":
            disagree += r[:2] != m[:2]
            print(f"{'DISAGREE' if r[:2] != m[:2] else 'note'} {fname}@{rate}: ref {r} / mine {m}")
    print(f"{iters} re-encoded layers, {disagree} disagreements")


if __name__ == "__main__":
    main()
