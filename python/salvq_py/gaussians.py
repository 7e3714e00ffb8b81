"""The explicit profile's binary32 reconstruction (§3.6): positions, the groups' values
(§7.3 with each Gaussian's step shift) and the rotation's largest component; Table 3-4. In a
progressive stream (§3.8.3, 0.15) with the refined precision: e = E[c] and Δ[g][c]."""
from __future__ import annotations

import numpy as np

from .explicit import OPACITY, ROTATION, SCALE, SH_DC, SH_REST, GGroup, GHead, GLayer
from .gatt import GattSymbols
from .quantizers import QNAN_BITS, reconstruct


def _quiet(x: np.ndarray) -> np.ndarray:
    """A NaN result is the quiet NaN 0x7FC00000 (§7.3)."""
    nan = np.isnan(x)
    if nan.any():
        x.view(np.uint32)[nan] = QNAN_BITS
    return x


def _pow2(e: np.ndarray) -> np.ndarray:
    """2^e in binary32, exact for −24 ≤ e ≤ 24 (integer exponents)."""
    return np.ldexp(np.float32(1), e.astype(np.int32)).astype(np.float32)


def positions(h: GHead, lay: GLayer, voxels: np.ndarray, sym: GattSymbols,
              bits: list | None = None) -> np.ndarray:
    """Step 1: q_a = v_a·2^e + w_a, h = voxel_size ⊗ 2^−e, x_a = origin_a ⊕ ((q_a ⊕ 0.5) ⊗ h);
    e = refine[c], or `bits[c]` (a progressive stream's E[c], §3.8.3)."""
    e = np.array(lay.refine if bits is None else bits, np.int64)[sym.size_class.astype(np.int64)]
    q = (voxels.astype(np.int64) << e[:, None]) + sym.refinement.astype(np.int64)
    with np.errstate(over="ignore", under="ignore"):
        hstep = (lay.voxel_size * _pow2(-e)).astype(np.float32)                       # [N]
        half = (q.astype(np.float32) + np.float32(0.5)).astype(np.float32)            # exact int → f32
        x = (h.origin()[None, :] + (half * hstep[:, None]).astype(np.float32)).astype(np.float32)
    return _quiet(x)


def group_values(grp: GGroup, rate: int, lay: GLayer, sym: GattSymbols, offset: int,
                 steps: np.ndarray | None = None) -> np.ndarray:
    """Step 2 for group g: Δ = (step ⊗ gain_r) ⊗ 2^s, z = B·float32(u), mean ⊕ (Δ ⊗ z);
    with `steps` (a progressive stream's Δ[g][c], [4] binary32, §3.8.3) Δ = steps[c]."""
    u = sym.coordinates[:, offset:offset + grp.d].astype(np.int64)
    n = u.shape[0]
    if steps is not None:
        delta = steps[sym.size_class.astype(np.int64)].astype(np.float32)
        means = np.broadcast_to(grp.mean[None, :], (n, grp.d))
        return reconstruct(u, grp.matrix, delta, means)
    if grp.g == 0:
        s = np.zeros(n, np.int64)
    else:
        s = np.array(lay.shift[grp.g - 1], np.int64)[sym.size_class.astype(np.int64)]
    with np.errstate(over="ignore", under="ignore"):
        delta = (grp.base_step(rate) * _pow2(s)).astype(np.float32)
    means = np.broadcast_to(grp.mean[None, :], (n, grp.d))
    return reconstruct(u, grp.matrix, delta, means)


def rotations(abc: np.ndarray, index: np.ndarray) -> np.ndarray:
    """Step 3, in binary64: t = 1 − ((a·a + b·b) + c·c), m = float32(sqrt(t)) if t > 0 else
    +0; the quaternion (w, x, y, z) has m at the rotation index and a, b, c elsewhere, in
    order."""
    a, b, c = (abc[:, k].astype(np.float64) for k in range(3))
    with np.errstate(over="ignore", invalid="ignore"):
        t = 1.0 - ((a * a + b * b) + c * c)           # binary64: the squares are exact
        pos = t > 0                                   # False for a NaN t
        m = np.zeros(t.shape, np.float32)             # +0
        m[pos] = np.sqrt(t[pos]).astype(np.float32)   # binary64 square root, then rounded
    q = np.empty((abc.shape[0], 4), np.float32)
    for k in range(4):
        sel = index == k
        q[sel, k] = m[sel]
        q[np.ix_(sel, [j for j in range(4) if j != k])] = abc[sel]
    return _quiet(q)


def reconstruct_gaussians(h: GHead, groups: list[GGroup], rate: int, lay: GLayer,
                          voxels: np.ndarray, sym: GattSymbols, precision=None) -> dict:
    """Table 3-4, in its order (`gaussian.sh_rest` only when B > 0). `precision` (a
    `grsy.Precision`: E[c] and Δ[g][c], §3.8.3) replaces refine[c] and (step ⊗ gain_r) ⊗ 2^s
    in a progressive stream."""
    offs = h.group_offsets()
    if precision is None:
        vals = {g.g: group_values(g, rate, lay, sym, offs[g.g]) for g in groups}
        bits = None
    else:
        vals = {g.g: group_values(g, rate, lay, sym, offs[g.g], precision.delta[g.g]) for g in groups}
        bits = precision.E
    out = {
        "gaussian.position": positions(h, lay, voxels, sym, bits),
        "gaussian.log_scale": vals[SCALE],
        "gaussian.opacity": vals[OPACITY][:, 0].copy(),
        "gaussian.rotation": rotations(vals[ROTATION], sym.rotation_index),
        "gaussian.sh_dc": vals[SH_DC],
    }
    if h.B > 0:
        out["gaussian.sh_rest"] = vals[SH_REST]
    return out
