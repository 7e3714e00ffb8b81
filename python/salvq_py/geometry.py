"""Anchor geometry (§8, `APOS` coding method 1, §1.6.4): an octree per tile with adaptive
contexts (§8.2, §8.3), direct nodes (§8.2, since 0.12: an isolated node's flag, then its
single voxel's octants as uniform 3-bit values) and a count per voxel (§8.4)."""
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


# The 26 neighbour offsets of §8.2's isolation test, d ∈ {−1, 0, 1}³ \ {(0, 0, 0)}.
_NEIGHBOURS = tuple((dx, dy, dz) for dz in (-1, 0, 1) for dy in (-1, 0, 1) for dx in (-1, 0, 1)
                    if (dx, dy, dz) != (0, 0, 0))

_OCTANT_BITS = 3                                # §8.2: one uniform 3-bit value per depth


def _too_many(tile: Tile, depth: int, n: int) -> SalvqError:
    return SalvqError("OctreeInvalid",
                      f"chunk APOS, tile {tile.index}: more nodes than anchors at depth {depth} "
                      f"({n} > {tile.count}) [§8.2]")


def _isolated(px: int, py: int, pz: int, node_set: set) -> bool:
    """§8.2: none of the 26 neighbours is in the depth-k list (a cell outside [0, 2^k)^3
    never is: `node_set` holds only cells inside it)."""
    for (dx, dy, dz) in _NEIGHBOURS:
        if (px + dx, py + dy, pz + dz) in node_set:
            return False
    return True


def _octree(dec: AnsDecoder, tile: Tile) -> list[tuple]:
    """§8.2 with §8.3's contexts: the tile's occupied voxels (cell-relative), in Morton order.

    `direct[j]` is None for an ordinary node, or the voxel v (depth-D cell) a direct node
    holds. Every loop is bounded: D levels, at most N_t nodes per level (checked before each
    append), 8 children or D − k octants per node."""
    D = tile.level
    Nt = tile.count
    occ = _Ctx(1024)                            # occupancy contexts (§8.3)
    dctx = _Ctx(4)                              # direct-flag contexts (§8.3, since 0.12)
    nodes: list[tuple] = [(0, 0, 0)]
    direct: list = [None]                       # the root is not direct
    for k in range(D):
        node_set = set(nodes)
        lim = 1 << k
        left = D - k                            # levels left below a depth-k node
        children: list[tuple] = []
        child_direct: list = []
        child_set: set = set()
        for (px, py, pz), dv in zip(nodes, direct):
            if dv is not None:                  # a direct node: its one child, no events
                if len(children) >= Nt:
                    raise _too_many(tile, k + 1, len(children) + 1)
                sh = left - 1
                c = (dv[0] >> sh, dv[1] >> sh, dv[2] >> sh)
                children.append(c)
                child_direct.append(dv)
                child_set.add(c)
                continue
            if _isolated(px, py, pz, node_set) and _event(dec, dctx, min(left, 4) - 1):
                vx, vy, vz = px, py, pz         # v = p, then one octant per depth k+1 … D
                for _ in range(left):
                    o = dec.decode_uniform(_OCTANT_BITS)
                    vx, vy, vz = 2 * vx + (o & 1), 2 * vy + ((o >> 1) & 1), 2 * vz + (o >> 2)
                if len(children) >= Nt:         # after the octants (§8.2)
                    raise _too_many(tile, k + 1, len(children) + 1)
                sh = left - 1
                dv = (vx, vy, vz)
                c = (vx >> sh, vy >> sh, vz >> sh)
                children.append(c)
                child_direct.append(dv)
                child_set.add(c)
                continue
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
                    if len(children) >= Nt:
                        raise _too_many(tile, k + 1, len(children) + 1)
                    children.append(c)
                    child_direct.append(None)
                    child_set.add(c)
                    occupied += 1
        nodes = children
        direct = child_direct
    return nodes


def decode_tile(body: bytes, tile: Tile) -> list[tuple]:
    """One tile's APOS body: returns its anchors' absolute voxels, in order (§8.2 - §8.4)."""
    dec = AnsDecoder(body)                      # §6.2.6 steps 1-3
    D = tile.level
    Nt = tile.count
    nodes = _octree(dec, tile)
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
