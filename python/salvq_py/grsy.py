"""Progressive streams (§3.8, 0.15): `GRSY` (§3.8.2), a refinement's symbols, one ANS body per
tile of the full layer (§10.2), refining the previous layer's coordinates and position bits in
place; and the precision a rate is reconstructed at (§3.8.3: E[c] position bits below a voxel,
the step Δ[g][c] divided by each refinement's factor in binary32)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .ans import AnsDecoder, AnsFault, EscapeOverflowFault, ans_error
from .entropy import payload_method
from .errors import SalvqError
from .explicit import SH_REST, SIZE_CLASSES, GGroup, GHead, GLayer, GRefine, rest_count_bits
from .gatt import HALF, LIMIT, GattSymbols, bitlen
from .tiles import Tile, split_tiles


@dataclass
class Precision:
    """§3.8.3: per size class c, E[c] position bits below a voxel and, per group g, the step
    Δ[g][c] (binary32)."""
    E: list                  # [4] ints
    delta: list              # [G] arrays of [4] float32

    @classmethod
    def full_layer(cls, groups: list[GGroup], rate: int, lay: GLayer) -> "Precision":
        """After the full layer (rate b): E[c] = GLAY's refine[c], Δ[g][c] = (step_g ⊗
        gain_(g,b)) ⊗ 2^shift, the step of §3.6 step 2 (shift 0 for the scale group)."""
        delta = []
        for grp in groups:
            row = np.empty(SIZE_CLASSES, np.float32)
            for c in range(SIZE_CLASSES):
                s = 0 if grp.g == 0 else lay.shift[grp.g - 1][c]
                with np.errstate(over="ignore", under="ignore"):
                    # 2^s exact in binary32 (|s| ≤ 16); one binary32 multiplication
                    row[c] = np.float32(grp.base_step(rate) * np.float32(np.ldexp(np.float32(1), s)))
            delta.append(row)
        return cls(list(lay.refine), delta)

    def refined(self, ref: GRefine) -> "Precision":
        """One refinement: E[c] ← E[c] + refine[c], Δ[g][c] ← Δ[g][c] ⊘ float32(factor[g][c])
        (one binary32 division, round-to-nearest-even; exact when the factor is 1)."""
        E = [e + r for e, r in zip(self.E, ref.refine)]
        delta = []
        for g, row in enumerate(self.delta):
            new = np.empty(SIZE_CLASSES, np.float32)
            for c in range(SIZE_CLASSES):
                with np.errstate(over="ignore", under="ignore", invalid="ignore"):
                    new[c] = np.float32(row[c]) / np.float32(ref.factor[g][c])   # binary32 ⊘
            delta.append(new)
        return Precision(E, delta)


def _context_class(has_ref: bool, r_ref: int, u_prev: int) -> int:
    """§3.8.2: without a reference 0 if the value's previous coordinate is 0, else 1; with one
    2 + min(bitlen(|r'|), 5), r' the reference's symbol in this refinement (classes 0 … 7)."""
    if not has_ref:
        return 0 if u_prev == 0 else 1
    return 2 + min(bitlen(abs(r_ref)), 5)


def _tile(dec: AnsDecoder, tile: Tile, h: GHead, ref: GRefine, voxels: np.ndarray,
          sym: GattSymbols) -> None:
    """The events of one tile's Gaussians (§3.8.2), in order; contexts start afresh. The
    coordinates and position bits of `sym` are refined in place, Gaussian by Gaussian."""
    dims, offs = h.group_dims(), h.group_offsets()
    pl = ref.pred_level
    vox = voxels[tile.start:tile.start + tile.count].tolist()
    classes = sym.size_class[tile.start:tile.start + tile.count].tolist()
    prev_u = prev_r = None              # the reference's (refined) coordinates and symbols
    for i in range(tile.count):
        n = tile.start + i
        c = classes[i]
        has_ref = (i > 0 and classes[i - 1] == c
                   and all((vox[i - 1][a] >> pl) == (vox[i][a] >> pl) for a in range(3)))
        u = sym.coordinates[n].tolist()             # the previous layer's coordinates
        r = [0] * h.D
        for g, d in enumerate(dims):
            if g == 1:                              # position bits, after the scale group
                e = ref.refine[c]
                for a in range(3):
                    w = int(sym.refinement[n, a])   # the bits below the voxel so far
                    for _ in range(e):
                        w = 2 * w + dec.decode_binary(HALF)
                    sym.refinement[n, a] = w
            m = ref.factor[g][c]
            if m == 1:                              # not refined: coordinates stay, symbols 0
                continue
            half = m // 2
            o = ref.scale_offset[g][c]
            predict = has_ref and ref.predict[g] == 1
            coded = d
            if g == SH_REST:                        # the sh_rest count, as §3.5's
                bits = rest_count_bits(h)
                node = 1
                for _ in range(bits):
                    node = 2 * node + dec.decode_binary(ref.rest_count_freq[node - 1])
                coded = node - (1 << bits)
                if coded > d:
                    raise SalvqError("ValueInvalid",
                                     f"GRSY.rest_count[{i}] = {coded}: above the sh_rest group's {d} "
                                     f"values (tile {tile.index}, Gaussian {n}) [§3.8.2]")
            for v in range(offs[g], offs[g] + d):
                q = u[v] * m                        # the old cell's centre
                p = min(max(prev_u[v], q - half), q + half) if predict else q
                if v - offs[g] < coded:
                    x = _context_class(has_ref, prev_r[v] if has_ref else 0, u[v])
                    k = min(max(ref.scale_table[v][x] + o, 0), 127)
                    r[v] = dec.decode_symbol(k)     # §6.4, or §6.3.6 when k ≥ 64
                else:
                    r[v] = 0                        # no event
                u[v] = p + r[v]
                if abs(u[v]) > LIMIT:
                    raise SalvqError("ValueInvalid",
                                     f"GRSY.coordinate[{i}, {v}] = {u[v]}: above 2^24 in magnitude "
                                     f"(tile {tile.index}, Gaussian {n}) [§3.8.2]")
        sym.coordinates[n] = u
        prev_u, prev_r = u, r


def decode_grsy(payload: bytes, h: GHead, ref: GRefine, tiles: list[Tile], voxels: np.ndarray,
                sym: GattSymbols, sel: list[bool] | None = None) -> GattSymbols:
    """§3.8.2: §1.6 steps 1-2, the tile framing of §10.2 (the full layer's tiles), then tile by
    tile (the lowest tile's error first, §10.3): §6.2.6 steps 1-3, the events, §6.2.6 step 5.
    Returns the refined symbols (a copy: `sym`, the previous layer's, is left as it was). In a
    region decode (§10.3.1 step 3) only the tiles marked in `sel` are decoded."""
    payload_method("GRSY", payload, 1)
    bodies = split_tiles("GRSY", payload, 1, len(tiles))
    out = GattSymbols(sym.coordinates.copy(), sym.rotation_index.copy(), sym.size_class.copy(),
                      sym.refinement.copy())
    for body, t in zip(bodies, tiles):
        if sel is not None and not sel[t.index]:
            continue
        try:
            dec = AnsDecoder(body)
            _tile(dec, t, h, ref, voxels, out)
            dec.finish()
        except AnsFault as f:
            raise ans_error("GRSY", t.index, f) from None
        except EscapeOverflowFault:
            raise SalvqError("EscapeOverflow",
                             f"chunk GRSY, tile {t.index}: escape prefix of 31 zero bits [§6.4]") from None
    return out
