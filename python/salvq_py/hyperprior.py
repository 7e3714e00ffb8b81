"""The integer hyperprior (§5): `MLPS` (§1.6.2, Table 5-1), grid features (§5.1), touched
entries (§5.2) and `GRID` (§1.6.1), the fixed-point context MLP (§5.3), steps and scale
indices (§5.4) and the binary32 means and steps of reconstruction (§5.5).

Integer arithmetic: the MLP sums are computed with float64 matrix products, which are exact
here because every product and partial sum is an integer below 2^53 in magnitude
(layer 0: |w0 x| <= 2^23, at most 2048 terms plus an i32 bias, < 2^35; layer 1:
|w1 a| <= 2^30, at most 4096 terms plus an i32 bias, < 2^43), then wrapped to i32 (wrapping
commutes with the ring operations, so wrapping at the end equals wrapping every step).
Everything else that can exceed 64 bits (§5.4) uses Python integers.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import SalvqError
from .model import Dims, level_entries
from .tables import THRESHOLD_Q16

W_BITS = 10   # §5.1 weight bits


def rshr(a: int, s: int) -> int:
    """§5: floor((a + 2^(s-1)) / 2^s) for s >= 1, a for s = 0 (exact, any width)."""
    if s == 0:
        return a
    return (a + (1 << (s - 1))) >> s


def wrap_i32(a: np.ndarray) -> np.ndarray:
    return ((a + (1 << 31)) & 0xFFFFFFFF) - (1 << 31)


# --------------------------------------------------------------------------- MLPS (§1.6.2)

@dataclass
class IntMlp:
    a0: int
    shift0: int
    a1: np.ndarray        # [Cout] int64
    w0: np.ndarray        # [H, Cin] int64
    b0: np.ndarray        # [H] int64
    w1: np.ndarray        # [Cout, H] int64
    b1: np.ndarray        # [Cout] int64

    @property
    def qh(self) -> int:
        return 8 + self.a0 - self.shift0

    @property
    def E(self) -> np.ndarray:
        """E_o = Qh + a1[o]: the unit exponent of each output."""
        return self.qh + self.a1


def scaffold_specs(d: Dims) -> list[tuple[str, tuple]]:
    out = []
    for name, o in (("mlp_opacity", d.K), ("mlp_cov", 7 * d.K), ("mlp_color", 3 * d.K)):
        out += [(f"{name}.0.weight", (d.Hs, d.F + d.V)), (f"{name}.0.bias", (d.Hs,)),
                (f"{name}.2.weight", (o, d.Hs)), (f"{name}.2.bias", (o,))]
    return out


def scaffold_value_count(d: Dims) -> int:
    """The elements of Table 2-1 rows 19-30: 3·Hs·(F + V + 1) + 11·K·Hs + 11·K."""
    return sum(int(np.prod(s)) for _, s in scaffold_specs(d))


# Table 1-7: context_precision -> (bytes per w0/w1 value, storage dtype); i8 values are
# sign-extended to the same §5.3 integers.
CONTEXT_PRECISION = {0: (2, "<i2"), 1: (1, "i1")}


def mlps_context_length(d: Dims, w: int = 2) -> int:
    """§1.6.2 `context(w)`: the bytes from `context_precision` to `b1` (Table 5-1), with `w`
    the bytes of each `w0`/`w1` value (Table 1-7)."""
    return 3 + d.Cout + w * d.H * d.Cin + 4 * d.H + w * d.Cout * d.H + 4 * d.Cout


# Table 1-6: scaffold_precision -> (bytes per value, little-endian storage dtype)
SCAFFOLD_PRECISION = {0: (4, "<f4"), 1: (2, "<f2")}


def mlps_body_length(d: Dims, scaffold_precision: int = 0, context_precision: int = 0) -> int:
    w = CONTEXT_PRECISION[context_precision][0]
    return (mlps_context_length(d, w) + 1
            + SCAFFOLD_PRECISION[scaffold_precision][0] * scaffold_value_count(d))


def parse_mlps(payload: bytes, d: Dims) -> tuple[IntMlp, dict]:
    """§1.6.2 (after §1.6 steps 1-2; the length checks of step 3 are §1.6.2's own, in its
    order, steps 1-7): the integer MLP (w0/w1 as i16 or i8, Table 1-7) and the Scaffold-GS
    tensors (binary32 or binary16, Table 1-6). Reported lengths are whole payload lengths
    (1 + body), as §1.6 step 3."""
    body = payload[1:]
    H, Cin, Cout = d.H, d.Cin, d.Cout
    scaffold_n = scaffold_value_count(d)
    # step 1: an empty body (the expected length as for i16 weights and binary32 values)
    if len(body) == 0:
        raise SalvqError("ChunkSizeMismatch",
                         f"chunk MLPS: payload length {len(payload)}, expected "
                         f"{1 + mlps_context_length(d, 2) + 1 + 4 * scaffold_n} [§1.6.2]")
    # step 2: context_precision
    cprec = body[0]
    if cprec not in CONTEXT_PRECISION:
        raise SalvqError("FieldOutOfRange",
                         f"MLPS context_precision = {cprec}, range 0 … 1 [§1.6.2, Table 1-7]")
    w, wdtype = CONTEXT_PRECISION[cprec]
    context = mlps_context_length(d, w)
    # step 3: a body shorter than context(w) + 1
    if len(body) < context + 1:
        raise SalvqError("ChunkSizeMismatch",
                         f"chunk MLPS: payload length {len(payload)}, expected "
                         f"{1 + context + 1 + 4 * scaffold_n} (context_precision {cprec}) [§1.6.2]")
    # step 4: scaffold_precision, the body's byte at offset context(w)
    precision = body[context]
    if precision not in SCAFFOLD_PRECISION:
        raise SalvqError("FieldOutOfRange",
                         f"MLPS scaffold_precision = {precision}, range 0 … 1 [§1.6.2, Table 1-6]")
    nbytes, dtype = SCAFFOLD_PRECISION[precision]
    # step 5: the exact body length
    if len(body) != context + 1 + nbytes * scaffold_n:
        raise SalvqError("ChunkSizeMismatch",
                         f"chunk MLPS: payload length {len(payload)}, expected "
                         f"{1 + context + 1 + nbytes * scaffold_n} (context_precision {cprec}, "
                         f"scaffold_precision {precision}) [§1.6.2]")
    a0 = body[1]
    shift0 = body[2]
    a1 = np.frombuffer(body, np.uint8, Cout, 3).astype(np.int64)
    pos = 3 + Cout
    w0 = np.frombuffer(body, wdtype, H * Cin, pos).astype(np.int64).reshape(H, Cin)
    pos += w * H * Cin
    b0 = np.frombuffer(body, "<i4", H, pos).astype(np.int64)
    pos += 4 * H
    w1 = np.frombuffer(body, wdtype, Cout * H, pos).astype(np.int64).reshape(Cout, H)
    pos += w * Cout * H
    b1 = np.frombuffer(body, "<i4", Cout, pos).astype(np.int64)
    pos += 4 * Cout
    assert pos == context
    # step 6: the fixed-point shifts
    if a0 > 30:
        raise SalvqError("FieldOutOfRange", f"MLPS w0_frac_bits = {a0}, range 0 … 30 [§1.6.2]")
    if shift0 > min(31, 8 + a0):
        raise SalvqError("FieldOutOfRange",
                         f"MLPS shift0 = {shift0}, range 0 … {min(31, 8 + a0)} [§1.6.2]")
    for o in range(Cout):
        if a1[o] > 30:
            raise SalvqError("FieldOutOfRange",
                             f"MLPS w1_frac_bits[{o}] = {int(a1[o])}, range 0 … 30 [§1.6.2]")
    pos += 1                                   # scaffold_precision
    # step 7: every Scaffold-GS value finite
    tensors = {}
    for name, shape in scaffold_specs(d):
        n = int(np.prod(shape))
        values = np.frombuffer(body, dtype, n, pos)
        bad = np.nonzero(~np.isfinite(values))[0]
        if bad.size:
            idx = np.unravel_index(int(bad[0]), shape)
            raise SalvqError("NonFiniteValue",
                             f"{name}[{', '.join(str(int(i)) for i in idx)}]: value is not finite [§1.6.2]")
        # binary16 -> binary32 is exact (subnormals and -0.0 included); binary32 keeps its bits
        tensors[name] = values.astype("<f4").reshape(shape).copy()
        pos += nbytes * n
    assert pos == len(body)
    return IntMlp(int(a0), int(shift0), a1, w0, b0, w1, b1), tensors


def _scaled_f32(values: np.ndarray, exps: np.ndarray) -> np.ndarray:
    """float32(value * 2^-exp), the exact rational rounded once (float64 holds it exactly)."""
    return (values.astype(np.float64) * np.exp2(-exps.astype(np.float64))).astype(np.float32)


def mlp_grid_tensors(mlp: IntMlp) -> dict:
    """§5.3: the decoded model's `mlp_grid.*` are the integers times their units, in binary32."""
    E = mlp.E
    return {
        "mlp_grid.0.weight": _scaled_f32(mlp.w0, np.full(mlp.w0.shape, mlp.a0)),
        "mlp_grid.0.bias": _scaled_f32(mlp.b0, np.full(mlp.b0.shape, 8 + mlp.a0)),
        "mlp_grid.2.weight": _scaled_f32(mlp.w1, np.broadcast_to(mlp.a1[:, None], mlp.w1.shape)),
        "mlp_grid.2.bias": _scaled_f32(mlp.b1, E),
    }


# --------------------------------------------------------------------------- grid (§5.1, §5.2)

@dataclass
class Level:
    tensor: int          # 0: grid_3d, 1: grid_xy, 2: grid_xz, 3: grid_yz
    axes: tuple          # coordinate axes (x = 0, y = 1, z = 2)
    r: int
    t: int
    start: int           # first entry of the level in its tensor

    @property
    def dense(self) -> bool:
        return (self.r + 1) ** len(self.axes) <= (1 << self.t)


def grid_levels(d: Dims) -> list[Level]:
    """The levels in feature order (§2.4, §5.1 step 4): 3D, then xy, xz, yz."""
    levels = []
    start = 0
    for r in d.res3:
        levels.append(Level(0, (0, 1, 2), r, d.T3, start))
        start += level_entries(r, 3, d.T3)
    for ti, axes in ((1, (0, 1)), (2, (0, 2)), (3, (1, 2))):
        start = 0
        for r in d.res2:
            levels.append(Level(ti, axes, r, d.T2, start))
            start += level_entries(r, 2, d.T2)
    return levels


_PRIMES = (1, 2654435761, 805459861)


def _axis_cell_weights(v: np.ndarray, r: int, B: int):
    """§5.1 step 1 for one axis: cell and the upper weight w1 (10 bits)."""
    X = (2 * v + 1) * r
    cell = X >> (B + 1)
    frac = X & ((1 << (B + 1)) - 1)
    if B + 1 >= W_BITS:
        w1 = frac >> (B + 1 - W_BITS)
    else:
        w1 = frac << (W_BITS - B - 1)
    return cell, w1


def level_corners(level: Level, voxels: np.ndarray, B: int):
    """Entries [N, 2^dim] (in the level's tensor) and weights [N, 2^dim] of every anchor's
    corners; corner n = dx + 2 dy (+ 4 dz)."""
    dim = len(level.axes)
    cells, w1s = [], []
    for a in level.axes:
        c, w1 = _axis_cell_weights(voxels[:, a], level.r, B)
        cells.append(c)
        w1s.append(w1)
    n = voxels.shape[0]
    entries = np.empty((n, 1 << dim), np.int64)
    weights = np.empty((n, 1 << dim), np.int64)
    mask = (1 << level.t) - 1
    r1 = level.r + 1
    for corner in range(1 << dim):
        idx = np.zeros(n, np.int64)
        w = np.ones(n, np.int64)
        for ai in range(dim):
            bit = (corner >> ai) & 1
            coord = cells[ai] + bit
            w = w * (w1s[ai] if bit else ((1 << W_BITS) - w1s[ai]))
            if level.dense:
                idx = idx + coord * (r1 ** ai)
            else:
                idx = idx ^ ((coord * _PRIMES[ai]) & 0xFFFFFFFF)
        if not level.dense:
            idx = idx & mask
        entries[:, corner] = idx + level.start
        weights[:, corner] = w
    return entries, weights


def touched_entries(d: Dims, voxels: np.ndarray) -> list[np.ndarray]:
    """§5.2: the sorted touched entries of grid_3d, grid_xy, grid_xz, grid_yz."""
    sizes = [d.E3, d.E2, d.E2, d.E2]
    masks = [np.zeros(s, bool) for s in sizes]
    for lv in grid_levels(d):
        ent, _ = level_corners(lv, voxels, d.coord_bits)
        masks[lv.tensor][ent.ravel()] = True
    return [np.nonzero(m)[0] for m in masks]


GRID_NAMES = ("hyperprior.grid_3d", "hyperprior.grid_xy", "hyperprior.grid_xz", "hyperprior.grid_yz")


def grid_body_length(d: Dims, touched: list[np.ndarray]) -> int:
    T = sum(int(t.size) for t in touched)
    return (d.C * T + 7) // 8


def parse_grid(body: bytes, d: Dims, touched: list[np.ndarray]) -> dict:
    """§1.6.1 (after the length check): touched entries' bits, untouched entries +1."""
    C = d.C
    T = sum(int(t.size) for t in touched)
    nbits = C * T
    bits = np.unpackbits(np.frombuffer(body, np.uint8), bitorder="little")
    if bits[nbits:].any():
        raise SalvqError("PaddingBitsSet", "chunk GRID: padding bits are not zero [§1.6.1]")
    vals = np.where(bits[:nbits] == 1, 1, -1).astype(np.int8)
    out = {}
    pos = 0
    sizes = [d.E3, d.E2, d.E2, d.E2]
    for ti, name in enumerate(GRID_NAMES):
        g = np.ones((sizes[ti], C), np.int8)
        n = touched[ti].size
        g[touched[ti]] = vals[pos:pos + n * C].reshape(n, C)
        pos += n * C
        out[name] = g
    return out


def grid_features(d: Dims, voxels: np.ndarray, grids: dict) -> np.ndarray:
    """§5.1: the [N, Cin] integer features (units 2^-8)."""
    n = voxels.shape[0]
    feats = np.empty((n, d.Cin), np.int64)
    tensors = [grids[name].astype(np.int64) for name in GRID_NAMES]
    col = 0
    for lv in grid_levels(d):
        ent, w = level_corners(lv, voxels, d.coord_bits)
        g = tensors[lv.tensor][ent]                 # [N, corners, C]
        A = (w[:, :, None] * g).sum(axis=1)         # units 2^-30 (3D) or 2^-20 (2D)
        sh = 22 if len(lv.axes) == 3 else 12
        feats[:, col:col + d.C] = (A + (1 << (sh - 1))) >> sh
        col += d.C
    return feats


def run_mlp(mlp: IntMlp, x: np.ndarray) -> np.ndarray:
    """§5.3 steps 1-3: [N, Cout] wrapped i32 outputs (as int64)."""
    s = x.astype(np.float64) @ mlp.w0.T.astype(np.float64)
    s = wrap_i32(s.astype(np.int64) + mlp.b0[None, :])
    if mlp.shift0:
        s = (s + (1 << (mlp.shift0 - 1))) >> mlp.shift0
    a = np.clip(s, 0, 32767)
    y = a.astype(np.float64) @ mlp.w1.T.astype(np.float64)
    return wrap_i32(y.astype(np.int64) + mlp.b1[None, :])


# --------------------------------------------------------------------------- §5.4, §5.5

def decompose(G_bits: int) -> tuple[int, int]:
    """§5.4 step 2: G = m * 2^e."""
    be = (G_bits >> 23) & 0xFF
    fr = G_bits & 0x7FFFFF
    if be > 0:
        return fr + (1 << 23), be - 150
    return max(fr, 1), -149


def step_index(alpha: int, E: int) -> int:
    """§5.4 step 1: a = clamp(rshr(16 alpha, E), -64, 64)."""
    return min(max(rshr(16 * alpha, E), -64), 64)


def scale_thresholds(m: int, e: int, factor: int, E: int) -> np.ndarray:
    """§5.4 step 3 as thresholds on y: k = #{j : y >= thr[j]} with the comparison
    y * 2^(32-E-e) >= theta_j * m * factor done exactly."""
    sh = 32 - E - e
    cap = 1 << 40               # y < 2^31: any threshold above it is never reached
    thr = []
    for j in range(1, 64):
        rhs = THRESHOLD_Q16[j] * m * factor
        if sh >= 0:
            t = -((-rhs) >> sh)           # ceil(rhs / 2^sh)
        else:
            t = rhs << (-sh)
        thr.append(min(t, cap))
    return np.array(thr, np.int64)


def scale_indices(sig: np.ndarray, E_rows: np.ndarray, m: int, e: int, factor: int,
                  cache: dict) -> np.ndarray:
    """Scale indices of one anchor's scale outputs `sig` (units 2^-E_rows)."""
    y = np.maximum(sig, 1)
    k = np.empty(sig.shape[0], np.int64)
    for E in np.unique(E_rows):
        key = (m, e, factor, int(E))
        thr = cache.get(key)
        if thr is None:
            thr = scale_thresholds(m, e, factor, int(E))
            cache[key] = thr
        sel = E_rows == E
        k[sel] = np.searchsorted(thr, y[sel], side="right")
    return k


def means_f32(mu: np.ndarray, E_rows: np.ndarray) -> np.ndarray:
    """§5.5 step 1: float32(mu * 2^-E)."""
    return _scaled_f32(mu, np.broadcast_to(E_rows, mu.shape))
