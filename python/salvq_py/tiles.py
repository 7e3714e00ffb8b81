"""Tiles (§10): the tile table `TILS` (§10.1), the framing of tiled entropy-coded chunks
(§10.2) and the box and order checks after `APOS` (§10.1)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import SalvqError


@dataclass
class Tile:
    index: int
    start: int
    count: int           # N_t
    level: int           # D_t
    cell: tuple
    box: tuple           # min x, y, z, max x, y, z


def parse_tils(payload: bytes, N: int, coord_bits: int) -> list[Tile]:
    """§10.1 after §1.6 steps 1-2 (coding_method 0 already checked), for N anchors (the
    anchors profile) or N Gaussians and the layer's `coord_bits` (the explicit profile, §3.4)."""
    if len(payload) < 5:
        raise SalvqError("ChunkSizeMismatch", f"chunk TILS: payload length {len(payload)}, expected 5 [§10.1]")
    T = int.from_bytes(payload[1:5], "little")
    if not 1 <= T <= N:
        raise SalvqError("FieldOutOfRange", f"TILS field tile_count = {T}, range 1 … {N} [§10.1]")
    if len(payload) != 5 + 41 * T:
        raise SalvqError("ChunkSizeMismatch",
                         f"chunk TILS: payload length {len(payload)}, expected {5 + 41 * T} [§10.1]")
    tiles = []
    pos = 5
    start = 0
    B = coord_bits
    for t in range(T):
        cnt = int.from_bytes(payload[pos:pos + 4], "little")
        # at least one anchor for each later tile; the last tile makes it N
        hi = N - start - (T - 1 - t)
        lo = hi if t == T - 1 else 1
        if not lo <= cnt <= hi:
            raise SalvqError("FieldOutOfRange",
                             f"TILS tile {t}: field tile_anchors = {cnt}, range {lo} … {hi} [§10.1]")
        level = payload[pos + 4]
        if level > B:
            raise SalvqError("FieldOutOfRange",
                             f"TILS tile {t}: field cell_level = {level}, range 0 … {B} [§10.1]")
        cell = tuple(int.from_bytes(payload[pos + 5 + 4 * i:pos + 9 + 4 * i], "little") for i in range(3))
        for i, c in enumerate(cell):
            if c >= 1 << (B - level):
                raise SalvqError("FieldOutOfRange",
                                 f"TILS tile {t}: field cell[{i}] = {c}, range 0 … {(1 << (B - level)) - 1} [§10.1]")
        box = tuple(int.from_bytes(payload[pos + 17 + 4 * i:pos + 21 + 4 * i], "little") for i in range(6))
        tiles.append(Tile(t, start, cnt, level, cell, box))
        start += cnt
        pos += 41
    return tiles


def split_tiles(chunk: str, payload: bytes, offset: int, T: int) -> list[bytes]:
    """§10.2: T u32 lengths then the bodies, which must use up the payload exactly."""
    if len(payload) - offset < 4 * T:
        raise SalvqError("Truncated",
                         f"chunk {chunk}: payload too short for its {T} tile lengths [§10.2]")
    lengths = [int.from_bytes(payload[offset + 4 * i:offset + 4 * i + 4], "little") for i in range(T)]
    pos = offset + 4 * T
    expected = pos + sum(lengths)
    if expected != len(payload):
        raise SalvqError("ChunkSizeMismatch",
                         f"chunk {chunk}: payload length {len(payload)}, the tile lengths imply {expected} [§10.2]")
    bodies = []
    for n in lengths:
        bodies.append(payload[pos:pos + n])
        pos += n
    return bodies


def morton(v) -> int:
    """§2.2 Morton code of (x, y, z)."""
    code = 0
    x, y, z = (int(c) for c in v)
    for i in range(21):
        code |= ((x >> i) & 1) << (3 * i) | ((y >> i) & 1) << (3 * i + 1) | ((z >> i) & 1) << (3 * i + 2)
    return code


def check_tiles(tiles: list[Tile], voxels: np.ndarray) -> None:
    """§10.1 after APOS: per tile in order, its box, then its order against the previous tile."""
    prev_last = None
    for t in tiles:
        v = voxels[t.start:t.start + t.count]
        box = tuple(int(a) for a in v.min(axis=0)) + tuple(int(a) for a in v.max(axis=0))
        if box != t.box:
            raise SalvqError("TileBoxMismatch",
                             f"tile {t.index}: stated box {t.box}, its anchors' box {box} [§10.1]")
        if prev_last is not None and morton(v[0]) <= morton(prev_last):
            raise SalvqError("TileOrder",
                             f"tile {t.index}: first voxel {tuple(int(a) for a in v[0])} does not come after "
                             f"the previous tile's last voxel {tuple(int(a) for a in prev_last)} in Morton order [§10.1]")
        prev_last = v[-1]
