"""A minimal §6.2.3 ANS encoder and a layer re-encoder, to craft valid test streams.

`reencode_layer(data, rate, symbols)` re-codes the selected layer's AFEA/ASCL/AOFF of a stream
whose model chunks were edited (e.g. MLPS unit exponents, QUAN steps), with the scale indices
salvq_py computes for the edited model, so that the reference decoder and salvq_py can be
compared on streams the vectors do not cover. Testing aid only."""
from __future__ import annotations

import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
from salvq_py import decoder as D  # noqa: E402
from salvq_py.entropy import Prior, decode_amsk  # noqa: E402
from salvq_py.tables import P, scale_tables  # noqa: E402
from diff_fuzz import chunks, rebuild  # noqa: E402

L = 1 << 32


def encode_body(intervals: list[tuple[int, int]]) -> bytes:
    x = L
    words = []
    for c, f in reversed(intervals):
        if (x >> (64 - P)) >= f:
            words.append(x & 0xFFFFFFFF)
            x >>= 32
        x = (x // f << P) + c + x % f
    out = [x >> 32, x & 0xFFFFFFFF] + words[::-1]
    return b"".join(w.to_bytes(4, "little") for w in out)


def symbol_intervals(u: int, k: int) -> list[tuple[int, int]]:
    t = scale_tables()[k]
    r = t.radius
    if abs(u) <= r:
        s = u + r
        return [(t.cum[s], t.freq[s])]
    out = [(t.cum[t.escape], t.freq[t.escape])]
    w = abs(u) - r
    nb = w.bit_length() - 1
    half = 1 << (P - 1)
    bit = lambda b: (half if b else 0, half)  # noqa: E731
    out += [bit(0)] * nb + [bit(1)]
    out += [bit((w >> i) & 1) for i in range(nb - 1, -1, -1)]
    out.append(bit(1 if u < 0 else 0))
    return out


class _Capture(Exception):
    pass


def model_state(data: bytes, rate: int):
    """Run salvq_py's decoding up to the layer decode and capture its state."""
    captured = {}
    orig = D.decode_layer

    def grab(payloads, d, tiles, mask, prior, groups):
        captured.update(d=d, tiles=tiles, mask=mask, prior=prior, groups=groups)
        raise _Capture()

    D.decode_layer = grab
    try:
        D.decode_bytes(data, rate)
    except _Capture:
        pass
    finally:
        D.decode_layer = orig
    return captured


def reencode_layer(data: bytes, rate: int, symbols: dict) -> bytes:
    st = model_state(data, rate)
    d, tiles, mask, prior = st["d"], st["tiles"], st["mask"], st["prior"]
    kf, ks, ko = prior.k["feat"], prior.k["scaling"], prior.k["offsets"]
    bodies = {"AFEA": [], "ASCL": [], "AOFF": []}
    for t in tiles:
        ev = {"AFEA": [], "ASCL": [], "AOFF": []}
        for i in range(t.start, t.start + t.count):
            for j in range(d.F):
                ev["AFEA"] += symbol_intervals(int(symbols["feat"][i, j]), int(kf[i, j]))
            for j in range(d.S):
                ev["ASCL"] += symbol_intervals(int(symbols["scaling"][i, j]), int(ks[i, j]))
            for s in range(d.K):
                if mask[i, s]:
                    for c in range(3):
                        ev["AOFF"] += symbol_intervals(int(symbols["offsets"][i, s, c]), int(ko[i, 3 * s + c]))
        for tag in bodies:
            bodies[tag].append(encode_body(ev[tag]))
    coded = d.coded_rates()
    nth = coded.index(rate)
    for tag, bl in bodies.items():
        payload = bytes([1]) + b"".join(len(b).to_bytes(4, "little") for b in bl) + b"".join(bl)
        k = 0
        for ci, (pos, n, tg) in enumerate(chunks(data)):
            if tg == tag.encode():
                if k == nth:
                    data = rebuild(data, ci, payload)
                    break
                k += 1
    return data
