#!/usr/bin/env python3
"""Decode anchor voxel coordinates (APOS) of a SALVQ 0.8 stream, from spec/ only.

Written by an independent reader who saw spec/ and not src/ (2026-11-22), as a check that §1,
§6.2, §8 and §10 are complete: it matched the reference decoder voxel for voxel on a
20 000-anchor, 11-tile stream. Usage: `python3 apos_decode.py STREAM.salvq VOXELS.npy`, with
VOXELS.npy the int32 [N, 3] `anchor.voxel` of the reference decode. Needs numpy.
"""
import struct, sys
import numpy as np

P = 16
L = 1 << 32

# --- CRC-32C (§1.3): reflected poly 0x82F63B78 ---
_T = []
for n in range(256):
    c = n
    for _ in range(8):
        c = (c >> 1) ^ 0x82F63B78 if c & 1 else c >> 1
    _T.append(c)

def crc32c(b):
    c = 0xFFFFFFFF
    for x in b:
        c = _T[(c ^ x) & 0xFF] ^ (c >> 8)
    return c ^ 0xFFFFFFFF

assert crc32c(b"123456789") == 0xE3069283

class Err(Exception):
    pass

# --- ANS body (§6.2.5, §6.2.6) ---
class Ans:
    def __init__(self, body):
        if len(body) % 4 or len(body) < 8:
            raise Err("Framing")
        self.w = struct.unpack("<%dI" % (len(body) // 4), body)
        if self.w[0] == 0:
            raise Err("ZeroTopWord")
        self.x = (self.w[0] << 32) | self.w[1]
        self.pos = 2

    def bit(self, freq_one):  # §6.2.1 item 3, §6.2.4
        f1 = min(max(freq_one, 1), (1 << P) - 1)
        x = self.x
        q = x & ((1 << P) - 1)
        if q >= (1 << P) - f1:
            s, c, f = 1, (1 << P) - f1, f1
        else:
            s, c, f = 0, 0, (1 << P) - f1
        x = f * (x >> P) + (q - c)
        if x < L:
            if self.pos >= len(self.w):
                raise Err("OutOfWords")
            x = (x << 32) | self.w[self.pos]
            self.pos += 1
        self.x = x
        return s

    def finish(self):
        if self.pos != len(self.w):
            raise Err("WordsLeftOver")
        if self.x != L:
            raise Err("StateNotFinal")

# --- adaptive binary context (§8.3) ---
def coded(ans, ctx, j):
    c0, c1 = ctx[j]
    fo = min(max((c1 << P) // (c0 + c1), 1), (1 << P) - 1)
    b = ans.bit(fo)
    if b: c1 += 1
    else: c0 += 1
    if c0 + c1 > 256:
        c0, c1 = (c0 + 1) >> 1, (c1 + 1) >> 1
    ctx[j] = [c0, c1]
    return b

NB7 = lambda s0, s1, s2: [(s0, 0, 0), (0, s1, 0), (0, 0, s2), (s0, s1, 0), (s0, 0, s2), (0, s1, s2), (s0, s1, s2)]
FACES = [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)]

def decode_tile(body, N, D):
    ans = Ans(body)
    ctx = [[1, 1] for _ in range(1024)]
    nodes = [(0, 0, 0)]
    for k in range(D):
        nset = set(nodes)
        lim = 1 << k
        children, cset = [], set()
        for (x, y, z) in nodes:
            occ = 0
            for i in range(8):
                b0, b1, b2 = i & 1, (i >> 1) & 1, (i >> 2) & 1
                c = (2 * x + b0, 2 * y + b1, 2 * z + b2)
                if i == 7 and occ == 0:
                    bit = 1
                else:
                    s = (2 * b0 - 1, 2 * b1 - 1, 2 * b2 - 1)
                    n7 = 0
                    for d in NB7(*s):
                        q = (x + d[0], y + d[1], z + d[2])
                        if 0 <= q[0] < lim and 0 <= q[1] < lim and 0 <= q[2] < lim and q in nset:
                            n7 += 1
                    kf = sum(1 for d in FACES if (c[0] + d[0], c[1] + d[1], c[2] + d[2]) in cset)
                    kf = min(3, kf)
                    sib = min(3, occ)
                    j = ((i * 8 + n7) * 4 + kf) * 4 + sib
                    bit = coded(ans, ctx, j)
                if bit:
                    children.append(c); cset.add(c); occ += 1
                    if len(children) > N:
                        raise Err("OctreeInvalid more nodes than anchors depth %d" % (k + 1))
        nodes = children
    # §8.4 voxel counts
    cctx = [[1, 1] for _ in range(4)]
    out, total = [], 0
    for v in nodes:
        cnt, t = 1, 0
        total += 1
        if total > N:
            raise Err("OctreeInvalid counts above")
        while coded(ans, cctx, min(t, 3)):
            cnt += 1; t += 1; total += 1
            if total > N:
                raise Err("OctreeInvalid counts above")
        out.extend([v] * cnt)
    if total < N:
        raise Err("OctreeInvalid counts below")
    ans.finish()
    return out

def morton(v):
    m = 0
    for i in range(21):
        for a in range(3):
            m |= ((v[a] >> i) & 1) << (3 * i + a)
    return m

def decode(data):
    if data[:8] != b"\x89SALVQ\r\n": raise Err("SignatureMismatch")
    if len(data) < 12: raise Err("Truncated")
    major, minor, flags = struct.unpack_from("<BBH", data, 8)
    if major != 0: raise Err("UnsupportedMajorVersion")
    if minor != 8: raise Err("UnsupportedMinorVersion")
    if flags: raise Err("ReservedBitsSet")
    pos = 12
    order = ["HEAD", "MLPS", "QUAN", "TILS", "APOS", "GRID", "AMSK"]
    oi = 0
    N = coord_bits = None
    tiles = None
    voxels = None
    while True:
        R = len(data) - pos
        if R < 8: raise Err("Truncated chunk header")
        length, = struct.unpack_from("<I", data, pos)
        tag = data[pos + 4:pos + 8]
        if length > R - 8: raise Err("ChunkLengthPastEnd")
        if R - 8 - length < 4: raise Err("Truncated CRC")
        payload = data[pos + 8:pos + 8 + length]
        crc, = struct.unpack_from("<I", data, pos + 8 + length)
        if crc32c(tag + payload) != crc: raise Err("ChunkCrcMismatch %r" % tag)
        pos += 12 + length
        t = tag.decode("ascii")
        if t[0].islower():
            continue
        if oi < len(order):
            if t != order[oi]: raise Err("ChunkOrder expected %s got %s" % (order[oi], t))
            oi += 1
        if t == "HEAD":
            N, = struct.unpack_from("<I", payload, 0)
            coord_bits = payload[11]
        elif t == "TILS":
            assert payload[0] == 0
            T, = struct.unpack_from("<I", payload, 1)
            if not 1 <= T <= N: raise Err("FieldOutOfRange tile_count")
            if len(payload) != 5 + 41 * T: raise Err("ChunkSizeMismatch TILS")
            tiles = []
            for i in range(T):
                o = 5 + 41 * i
                na, = struct.unpack_from("<I", payload, o)
                lvl = payload[o + 4]
                cell = struct.unpack_from("<3I", payload, o + 5)
                box = struct.unpack_from("<6I", payload, o + 17)
                assert lvl <= coord_bits and all(c < (1 << (coord_bits - lvl)) for c in cell)
                tiles.append((na, lvl, cell, box))
            assert sum(t_[0] for t_ in tiles) == N
        elif t == "APOS":
            assert payload[0] == 1, "UnknownCodingMethod"
            T = len(tiles)
            if len(payload) < 1 + 4 * T: raise Err("Truncated APOS lengths")
            tb = struct.unpack_from("<%dI" % T, payload, 1)
            if 1 + 4 * T + sum(tb) != len(payload): raise Err("ChunkSizeMismatch APOS")
            o = 1 + 4 * T
            voxels = []
            prev_last = None
            for (na, lvl, cell, box), nb in zip(tiles, tb):
                rel = decode_tile(payload[o:o + nb], na, lvl)
                o += nb
                vs = [tuple((cell[a] << lvl) + v[a] for a in range(3)) for v in rel]
                arr = np.array(vs)
                if tuple(arr.min(0)) + tuple(arr.max(0)) != tuple(box):
                    raise Err("TileBoxMismatch")
                if prev_last is not None and morton(vs[0]) <= morton(prev_last):
                    raise Err("TileOrder")
                prev_last = vs[-1]
                voxels.extend(vs)
            return np.array(voxels, dtype=np.int32)
    return None

if __name__ == "__main__":
    data = open(sys.argv[1], "rb").read()
    v = decode(data)
    ref = np.load(sys.argv[2])
    print("decoded", v.shape, "reference", ref.shape)
    if v.shape == ref.shape:
        eq = np.all(v == ref, axis=1)
        print("rows equal: %d / %d" % (eq.sum(), len(ref)))
        print("MATCH" if eq.all() else "MISMATCH")
    else:
        n = min(len(v), len(ref))
        print("MISMATCH; first %d rows equal: %d" % (n, np.all(v[:n] == ref[:n], axis=1).sum()))
