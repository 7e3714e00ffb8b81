"""Anchor geometry (§8, `APOS` coding method 1, §1.6.4): an octree per tile with adaptive
contexts (§8.2, §8.3) and a count per voxel (§8.4)."""
from __future__ import annotations

import numpy as np

from .ans import AnsDecoder, AnsFault, ans_error
from .errors import SalvqError
from .tables import P
from .tiles import Tile

_ONE = 1 << P


class _Ctx:
    __slots__ = ("c0", "c1")

    def __init__(self, n: int):
        self.c0 = [1] * n
        self.c1 = [1] * n


def _event(dec: AnsDecoder, ctx: _Ctx, i: int) -> int:
    c0, c1 = ctx.c0[i], ctx.c1[i]
    f = min(max((c1 << P) // (c0 + c1), 1), _ONE - 1)
    bit = dec.decode_binary(f)
    if bit:
        c1 += 1
    else:
        c0 += 1
    if c0 + c1 > 256:
        c0 = (c0 + 1) >> 1
        c1 = (c1 + 1) >> 1
    ctx.c0[i], ctx.c1[i] = c0, c1
    return bit


_N7 = None


def decode_tile(body: bytes, tile: Tile) -> list[tuple]:
    """One tile's APOS body: returns its anchors' absolute voxels, in order (§8.2 - §8.4)."""
    dec = AnsDecoder(body)                      # §6.2.6 steps 1-3
    D = tile.level
    Nt = tile.count
    occ = _Ctx(1024)
    nodes = [(0, 0, 0)]
    for k in range(D):
        node_set = set(nodes)
        lim = 1 << k
        children: list[tuple] = []
        child_set: set = set()
        for (px, py, pz) in nodes:
            occupied = 0
            for i in range(8):
                b0, b1, b2 = i & 1, (i >> 1) & 1, (i >> 2) & 1
                c = (2 * px + b0, 2 * py + b1, 2 * pz + b2)
                if i == 7 and occupied == 0:
                    bit = 1
                else:
                    s0, s1, s2 = (1 if b0 else -1), (1 if b1 else -1), (1 if b2 else -1)
                    n7 = 0
                    for (dx, dy, dz) in ((s0, 0, 0), (0, s1, 0), (0, 0, s2), (s0, s1, 0),
                                         (s0, 0, s2), (0, s1, s2), (s0, s1, s2)):
                        q = (px + dx, py + dy, pz + dz)
                        if 0 <= q[0] < lim and 0 <= q[1] < lim and 0 <= q[2] < lim and q in node_set:
                            n7 += 1
                    cx, cy, cz = c
                    kf = 0
                    for q in ((cx - 1, cy, cz), (cx + 1, cy, cz), (cx, cy - 1, cz),
                              (cx, cy + 1, cz), (cx, cy, cz - 1), (cx, cy, cz + 1)):
                        if q in child_set:
                            kf += 1
                    kf = min(kf, 3)
                    sib = min(occupied, 3)
                    ctx = ((i * 8 + n7) * 4 + kf) * 4 + sib
                    bit = _event(dec, occ, ctx)
                if bit:
                    children.append(c)
                    child_set.add(c)
                    occupied += 1
                    if len(children) > Nt:
                        raise SalvqError("OctreeInvalid",
                                         f"chunk APOS, tile {tile.index}: more nodes than anchors at depth {k + 1} "
                                         f"({len(children)} > {Nt}) [§8.2]")
        nodes = children
    counts = _Ctx(4)
    total = 0
    out = []
    base = tuple(c << D for c in tile.cell)
    for leaf in nodes:
        m = 0
        while True:
            if total + 1 + m > Nt:
                raise SalvqError("OctreeInvalid",
                                 f"chunk APOS, tile {tile.index}: counts above the anchor count {Nt} [§8.4]")
            bit = _event(dec, counts, min(m, 3))
            if bit == 0:
                break
            m += 1
        cnt = 1 + m
        total += cnt
        v = (base[0] + leaf[0], base[1] + leaf[1], base[2] + leaf[2])
        out.extend([v] * cnt)
    if total < Nt:
        raise SalvqError("OctreeInvalid",
                         f"chunk APOS, tile {tile.index}: counts below the anchor count ({total} < {Nt}) [§8.4]")
    dec.finish()                                # §6.2.6 step 5
    return out


def decode_apos(bodies: list[bytes], tiles: list[Tile]) -> np.ndarray:
    """All tiles in order; the first error found is the lowest tile's (§10.3)."""
    voxels = []
    for body, tile in zip(bodies, tiles):
        try:
            voxels.extend(decode_tile(body, tile))
        except AnsFault as f:
            raise ans_error("APOS", tile.index, f) from None
    return np.array(voxels, np.int64).reshape(-1, 3)
