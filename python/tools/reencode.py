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
    """The intervals of symbol u under scale index k: §6.4 for k ≤ 63 (escapes included), a
    wide scale's high part and low bits for k = 64 … 127 (§6.3.6, since 0.14)."""
    if k >= 64:
        assert k <= 127
        b = (k - 56) >> 3
        q = u >> b                              # floor(u / 2^b), toward −∞
        return symbol_intervals(q, k - 8 * b) + [uniform_interval(u - (q << b), b)]
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

    def grab(payloads, d, tiles, mask, prior, groups, *region):   # region: sel, rows (§10.3.1)
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


# ------------------------------------------------------------------ explicit profile (§3.5)

def binary_interval(bit: int, freq_one: int) -> tuple[int, int]:
    """§6.2.1 item 3."""
    f1 = min(max(freq_one, 1), (1 << P) - 1)
    return ((1 << P) - f1, f1) if bit else (0, (1 << P) - f1)


def uniform_interval(v: int, b: int) -> tuple[int, int]:
    """§6.2.1 item 4 (since 0.12): a uniform value v of b bits owns [v·2^(P−b), (v + 1)·2^(P−b))."""
    assert 1 <= b <= 12 and 0 <= v < (1 << b)
    return (v << (P - b), 1 << (P - b))


def gatt_intervals(h, lay, tile, voxels, coords, rot_index, size_class, refinement):
    """The intervals of one tile's GATT body for the given decoded values, by §3.5 as salvq_py
    reads it (the encoder's side of `salvq_py.gatt._tile`)."""
    from salvq_py.explicit import ROTATION, SCALE, rest_count_bits
    from salvq_py.gatt import context_class, rescale
    from salvq_py.gatt import size_class as size_class_of
    dims, offs = h.group_dims(), h.group_offsets()
    pl = lay.pred_level
    out = []
    prev_u = prev_r = None
    prev_c = 0
    for i in range(tile.count):
        n = tile.start + i
        v_now, v_prev = voxels[n], voxels[n - 1]
        has_ref = i > 0 and all((int(v_prev[a]) >> pl) == (int(v_now[a]) >> pl) for a in range(3))
        u = [int(x) for x in coords[n]]
        r = [0] * h.D
        c = 0
        for g, d in enumerate(dims):
            if g == 1:
                c = size_class_of(u[offs[SCALE]:offs[SCALE] + 3], lay.size_threshold)
                assert c == size_class[n], "size class changed: pass the new one"
                e = lay.refine[c]
                for a in range(3):
                    w = int(refinement[n, a])
                    out += [binary_interval((w >> b) & 1, 1 << 15) for b in range(e - 1, -1, -1)]
            if g == ROTATION:
                hi, lo = int(rot_index[n]) >> 1, int(rot_index[n]) & 1
                out += [binary_interval(hi, lay.rotation_freq[0]),
                        binary_interval(lo, lay.rotation_freq[1 + hi])]
            s = 0 if g == 0 else lay.shift[g - 1][c]
            s_ref = 0 if g == 0 else lay.shift[g - 1][prev_c]
            o = 0 if g == 0 else lay.scale_offset[g - 1][c]
            for v in range(offs[g], offs[g] + d):
                p = rescale(prev_u[v], s_ref, s) if has_ref and lay.predict[g] == 1 else 0
                r[v] = u[v] - p
            coded = d
            if g == 4:                          # sh_rest (0.13): its count, down the tree
                coded = max([j + 1 for j in range(d) if r[offs[g] + j] != 0], default=0)
                bits = rest_count_bits(h)
                node = 1
                for b in range(bits - 1, -1, -1):
                    bit = (coded >> b) & 1
                    out.append(binary_interval(bit, lay.rest_count_freq[node - 1]))
                    node = 2 * node + bit
            for v in range(offs[g], offs[g] + coded):
                x = context_class(prev_r[v], s_ref, s) if has_ref else 0
                k = min(max(lay.scale_table[v][x] + o, 0), 127)   # 64 … 127: wide (0.14)
                out += symbol_intervals(r[v], k)
        prev_u, prev_r, prev_c = u, r, c
    return out


def encode_gatt(h, lay, tiles, voxels, coords, rot_index, size_class, refinement) -> bytes:
    """A GATT payload (coding_method 1, §10.2 framing) for the given values."""
    bodies = [encode_body(gatt_intervals(h, lay, t, voxels, coords, rot_index, size_class,
                                         refinement)) for t in tiles]
    return (bytes([1]) + b"".join(len(b).to_bytes(4, "little") for b in bodies)
            + b"".join(bodies))


# ------------------------------------------------------------------ progressive streams (§3.8.2)

def grsy_intervals(h, ref, tile, voxels, old, new, size_class, old_w, new_w, counts=None):
    """The intervals of one tile's GRSY body (§3.8.2) refining the coordinates `old` into `new`
    and the position bits `old_w` into `new_w`, by §3.8.2 as salvq_py reads it (the encoder's
    side of `salvq_py.grsy._tile`; the sh_rest count is the values up to the last nonzero
    symbol, or `counts[n]` for Gaussian n of the layer when given, even above d)."""
    from salvq_py.explicit import SH_REST, rest_count_bits
    dims, offs = h.group_dims(), h.group_offsets()
    pl = ref.pred_level
    out = []
    prev_u = prev_r = None
    for i in range(tile.count):
        n = tile.start + i
        c = int(size_class[n])
        v_now, v_prev = voxels[n], voxels[n - 1]
        has_ref = (i > 0 and int(size_class[n - 1]) == c
                   and all((int(v_prev[a]) >> pl) == (int(v_now[a]) >> pl) for a in range(3)))
        u_old = [int(x) for x in old[n]]
        u = [int(x) for x in new[n]]
        r = [0] * h.D
        for g, d in enumerate(dims):
            if g == 1:
                e = ref.refine[c]
                for a in range(3):
                    w = int(new_w[n, a])
                    assert w >> e == int(old_w[n, a]), "position bits must extend the old ones"
                    out += [binary_interval((w >> b) & 1, 1 << 15) for b in range(e - 1, -1, -1)]
            m = ref.factor[g][c]
            if m == 1:
                assert u[offs[g]:offs[g] + d] == u_old[offs[g]:offs[g] + d], "factor 1 keeps the group"
                continue
            half = m // 2
            o = ref.scale_offset[g][c]
            for v in range(offs[g], offs[g] + d):
                q = u_old[v] * m
                p = min(max(prev_u[v], q - half), q + half) if has_ref and ref.predict[g] == 1 else q
                r[v] = u[v] - p
            coded = d
            if g == SH_REST:
                coded = max([j + 1 for j in range(d) if r[offs[g] + j] != 0], default=0)
                if counts is not None and n in counts:
                    coded = counts[n]
                bits = rest_count_bits(h)
                node = 1
                for b in range(bits - 1, -1, -1):
                    bit = (coded >> b) & 1
                    out.append(binary_interval(bit, ref.rest_count_freq[node - 1]))
                    node = 2 * node + bit
                coded = min(coded, d)
            for v in range(offs[g], offs[g] + coded):
                if has_ref:
                    x = 2 + min(abs(prev_r[v]).bit_length(), 5)
                else:
                    x = 0 if u_old[v] == 0 else 1
                k = min(max(ref.scale_table[v][x] + o, 0), 127)
                out += symbol_intervals(r[v], k)
        prev_u, prev_r = u, r
    return out


def encode_grsy(h, ref, tiles, voxels, old, new, size_class, old_w, new_w, counts=None) -> bytes:
    """A GRSY payload (coding_method 1, §10.2 framing over the full layer's tiles)."""
    bodies = [encode_body(grsy_intervals(h, ref, t, voxels, old, new, size_class, old_w, new_w,
                                         counts)) for t in tiles]
    return (bytes([1]) + b"".join(len(b).to_bytes(4, "little") for b in bodies)
            + b"".join(bodies))
