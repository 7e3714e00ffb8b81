"""Region decodes (§10.3.1): the box, the tiles' world boxes, the selection, and the
re-basing of spatial regions (§7.6) onto the output (step 5)."""
from __future__ import annotations

import math

import numpy as np

from .tiles import Tile


class RegionError(ValueError):
    """A box that is no box (§10.3.1: the caller's error, not a stream error of Table 9-1)."""


def parse_region(text) -> tuple[float, ...]:
    """`x0,y0,z0,x1,y1,z1` (or six numbers) -> six binary64 values, min x, y, z then max x,
    y, z. Python's float() reads a decimal as the nearest binary64 (§11.7); infinities are
    allowed (`inf`, `-inf`), NaN and min > max are refused."""
    if isinstance(text, str):
        parts = text.split(",")
        try:
            box = tuple(float(p.strip()) for p in parts)
        except ValueError:
            raise RegionError(f"region {text!r}: not six comma-separated numbers") from None
    else:
        box = tuple(float(v) for v in text)
    if len(box) != 6:
        raise RegionError(f"region {text!r}: {len(box)} numbers, expected 6 "
                          "(min x, y, z, max x, y, z)")
    for i, v in enumerate(box):
        if math.isnan(v):
            raise RegionError(f"region {text!r}: value {i} is NaN [§10.3.1]")
    for a, axis in enumerate("xyz"):
        if box[a] > box[3 + a]:
            raise RegionError(f"region {text!r}: min {axis} = {box[a]!r} > max {axis} = "
                              f"{box[3 + a]!r} [§10.3.1]")
    return box


def tile_world_box(tile: Tile, origin_f32, voxel_size_f32) -> tuple[list, list]:
    """§10.3.1 step 1: lo_a = o_a + b_a·v, hi_a = o_a + (B_a + 1)·v in binary64. o_a and v
    convert exactly from binary32; b·v is exact in binary64 (≤ 22 × 24 significant bits, and
    binary64's exponent range holds every binary32 times 2^21), so Python's float product is
    exact and the float sum is the one rounding, to nearest, ties to even."""
    v = float(voxel_size_f32)
    lo, hi = [], []
    for a in range(3):
        o = float(origin_f32[a])
        lo.append(o + float(tile.box[a]) * v)
        hi.append(o + float(tile.box[3 + a] + 1) * v)
    return lo, hi


def select_tiles(tiles: list[Tile], origin_f32, voxel_size_f32, box) -> list[bool]:
    """§10.3.1 step 2: the closed test lo_a ≤ max_a and min_a ≤ hi_a on every axis."""
    sel = []
    for t in tiles:
        lo, hi = tile_world_box(t, origin_f32, voxel_size_f32)
        sel.append(all(lo[a] <= box[3 + a] and box[a] <= hi[a] for a in range(3)))
    return sel


def selected_rows(tiles: list[Tile], sel: list[bool]) -> np.ndarray:
    """The canonical indices of the selected tiles' anchors, in stream order."""
    parts = [np.arange(t.start, t.start + t.count, dtype=np.int64)
             for t, s in zip(tiles, sel) if s]
    return np.concatenate(parts) if parts else np.zeros(0, np.int64)


def rebase(region_starts: list, rows: np.ndarray) -> tuple[list, list]:
    """§10.3.1 step 5 for one group with R = len(region_starts) + 1 regions: returns the kept
    regions (original indices, in order) and their new starts (the first is 0). The new start
    of region r is the number of selected anchors whose canonical index is below start_r; a
    region whose new run is empty is removed; if none remains, region 0 is kept alone."""
    starts = [0] + [int(s) for s in region_starts]
    n = len(rows)
    new = [int(np.searchsorted(rows, s, side="left")) for s in starts] + [n]
    kept = [r for r in range(len(starts)) if new[r + 1] != new[r]]
    if not kept:
        return [0], [0]
    return kept, [new[r] for r in kept]
