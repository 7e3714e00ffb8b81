"""`GATT` (§3.5): the explicit profile's attribute symbols, one ANS body per tile (§10.2),
decoded under the causal integer prior (reference, context classes, size classes, position
refinement, step shifts, scale-index offsets; scale indices 0 … 127, from 64 on a wide scale,
§6.3.6, since 0.14)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .ans import AnsDecoder, AnsFault, EscapeOverflowFault, ans_error
from .entropy import payload_method
from .errors import SalvqError
from .explicit import ROTATION, SCALE, GHead, GLayer, rest_count_bits
from .tiles import Tile, split_tiles

LIMIT = 1 << 24             # |u| ≤ 2^24 (ValueInvalid above)
HALF = 1 << 15              # a refinement bit: freq_one = 2^15


@dataclass
class GattSymbols:
    """What §3.5 decodes for the layer's N Gaussians, in stream order."""
    coordinates: np.ndarray      # [N, D] the lattice coordinates u
    rotation_index: np.ndarray   # [N]
    size_class: np.ndarray       # [N]
    refinement: np.ndarray       # [N, 3] w per axis

    def take(self, rows: np.ndarray) -> "GattSymbols":
        """The rows of a region decode's output (§10.3.1 step 4)."""
        return GattSymbols(self.coordinates[rows], self.rotation_index[rows],
                           self.size_class[rows], self.refinement[rows])


def bitlen(x: int) -> int:
    """bitlen(0) = 0, bitlen(x) = ⌊log2 x⌋ + 1."""
    return x.bit_length()


def rescale(u: int, a: int, b: int) -> int:
    """rescale(u, a, b): coordinate u coded at shift a, predicting at shift b."""
    t = a - b
    if t >= 0:
        return min(max(u << t, -LIMIT), LIMIT)
    n = -t
    return (u + (1 << (n - 1))) >> n          # rshr(u, n), floor division by 2^n


def context_class(r_ref: int, s_ref: int, s: int) -> int:
    """With a reference: 1 + min(bitlen(|t|), 6), t = the reference's symbol rescaled from its
    step shift to this Gaussian's (classes 1 … 7; 0 without a reference is the caller's)."""
    return 1 + min(bitlen(abs(rescale(r_ref, s_ref, s))), 6)


def size_class(scale_u, thresholds) -> int:
    """How many of the three thresholds are ≤ the largest scale coordinate."""
    top = max(scale_u)
    return sum(1 for t in thresholds if t <= top)


def _tile(dec: AnsDecoder, tile: Tile, h: GHead, lay: GLayer, voxels: np.ndarray,
          out: GattSymbols) -> None:
    """The events of one tile's Gaussians (§3.5), in order; contexts start afresh."""
    dims, offs = h.group_dims(), h.group_offsets()
    pl = lay.pred_level
    vox = voxels[tile.start:tile.start + tile.count].tolist()
    prev_u = prev_r = None              # the reference's coordinates and symbols
    prev_c = 0                          # its size class
    for i in range(tile.count):
        n = tile.start + i
        has_ref = i > 0 and all((vox[i - 1][a] >> pl) == (vox[i][a] >> pl) for a in range(3))
        u = [0] * h.D
        r = [0] * h.D
        c = 0
        for g, d in enumerate(dims):
            if g == 1:                                  # after the scale group
                c = size_class(u[offs[SCALE]:offs[SCALE] + 3], lay.size_threshold)
                e = lay.refine[c]
                for a in range(3):
                    w = 0
                    for _ in range(e):
                        w = 2 * w + dec.decode_binary(HALF)
                    out.refinement[n, a] = w
                out.size_class[n] = c
            if g == ROTATION:
                hi = dec.decode_binary(lay.rotation_freq[0])
                lo = dec.decode_binary(lay.rotation_freq[1 + hi])
                out.rotation_index[n] = 2 * hi + lo
            s = 0 if g == 0 else lay.shift[g - 1][c]
            s_ref = 0 if g == 0 else lay.shift[g - 1][prev_c]
            o = 0 if g == 0 else lay.scale_offset[g - 1][c]
            predict = has_ref and lay.predict[g] == 1
            coded = d
            if g == 4:                                  # sh_rest: its count first
                bits = rest_count_bits(h)
                node = 1
                for _ in range(bits):
                    node = 2 * node + dec.decode_binary(lay.rest_count_freq[node - 1])
                coded = node - (1 << bits)
                if coded > d:
                    raise SalvqError("ValueInvalid",
                                     f"GATT.rest_count[{i}] = {coded}: above the sh_rest group's {d} "
                                     f"values (tile {tile.index}, Gaussian {n} of the layer) [§3.5]")
            for v in range(offs[g], offs[g] + d):
                if v - offs[g] < coded:
                    x = context_class(prev_r[v], s_ref, s) if has_ref else 0
                    k = min(max(lay.scale_table[v][x] + o, 0), 127)   # 64 … 127: wide (0.14)
                    r[v] = dec.decode_symbol(k)                          # §6.4 or §6.3.6
                else:
                    r[v] = 0
                p = rescale(prev_u[v], s_ref, s) if predict else 0
                u[v] = p + r[v]
                if abs(u[v]) > LIMIT:
                    raise SalvqError("ValueInvalid",
                                     f"GATT.coordinate[{i}, {v}] = {u[v]}: above 2^24 in magnitude "
                                     f"(tile {tile.index}, Gaussian {n} of the layer) [§3.5]")
        out.coordinates[n] = u
        prev_u, prev_r, prev_c = u, r, c


def decode_gatt(payload: bytes, h: GHead, lay: GLayer, tiles: list[Tile],
                voxels: np.ndarray, sel: list[bool] | None = None) -> GattSymbols:
    """§3.5: §1.6 steps 1-2, the tile framing of §10.2, then tile by tile (the lowest tile's
    error first, §10.3): §6.2.6 steps 1-3, the events, §6.2.6 step 5. In a region decode
    (§10.3.1 step 3) only the tiles marked in `sel` are decoded (the others' rows stay 0)."""
    payload_method("GATT", payload, 1)
    bodies = split_tiles("GATT", payload, 1, len(tiles))
    N = h.N
    out = GattSymbols(np.zeros((N, h.D), np.int32), np.zeros(N, np.uint8),
                      np.zeros(N, np.uint8), np.zeros((N, 3), np.int32))
    for body, t in zip(bodies, tiles):
        if sel is not None and not sel[t.index]:
            continue
        try:
            dec = AnsDecoder(body)
            _tile(dec, t, h, lay, voxels, out)
            dec.finish()
        except AnsFault as f:
            raise ans_error("GATT", t.index, f) from None
        except EscapeOverflowFault:
            raise SalvqError("EscapeOverflow",
                             f"chunk GATT, tile {t.index}: escape prefix of 31 zero bits [§6.4]") from None
    return out
