"""Anchor positions (A.7.3, A.7.4): HAC's normalization box and 16-bit quantization, the voxel
size and the integer voxel grid."""
from __future__ import annotations

import numpy as np

from .common import ANCHOR_ROUND_DIGITS, ExportError


def update_anchor_bound(anchor: np.ndarray):
    """HAC:scene/gaussian_model.py:update_anchor_bound, in float32 as HAC computes it:
    min * 1.2 if min < 0 else min * 0.8; max * 1.2 if max > 0 else max * 0.8."""
    import torch
    a = torch.from_numpy(anchor.astype(np.float32))
    lo = torch.min(a, dim=0, keepdim=True)[0]
    hi = torch.max(a, dim=0, keepdim=True)[0]
    for c in range(3):
        lo[0, c] = lo[0, c] * 1.2 if lo[0, c] < 0 else lo[0, c] * 0.8
        hi[0, c] = hi[0, c] * 1.2 if hi[0, c] > 0 else hi[0, c] * 0.8
    return lo.numpy()[0], hi.numpy()[0]


def quantize_anchor(anchor: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """HAC:utils/encodings.py:Quantize_anchor.forward, float32: the positions HAC renders and
    queries its hash grid with (get_anchor)."""
    import torch
    a = torch.from_numpy(anchor.astype(np.float32))
    mn = torch.from_numpy(lo.astype(np.float32))[None]
    mx = torch.from_numpy(hi.astype(np.float32))[None]
    interval = (mx - mn) * (1 / (2 ** ANCHOR_ROUND_DIGITS - 1)) + 1e-6
    q = torch.div(a - mn, interval, rounding_mode="floor")
    q = torch.clamp(q, 0, 2 ** ANCHOR_ROUND_DIGITS - 1)
    return (q * interval + mn).numpy()


def infer_voxel_size(pos: np.ndarray) -> float | None:
    """Largest v among min-gap / k (k = 1..16) for which every coordinate is within 1 % of a
    multiple of v (A.7.3); None when there is none."""
    gaps = []
    for c in range(3):
        u = np.unique(pos[:, c].astype(np.float64))
        d = np.diff(u)
        d = d[d > 1e-7 * max(1.0, float(np.abs(u).max(initial=0)))]
        if d.size:
            gaps.append(d.min())
    if not gaps:
        return None
    g = float(min(gaps))
    for k in range(1, 17):
        v = g / k
        r = pos.astype(np.float64) / v
        if np.abs(r - np.round(r)).max() <= 0.01:
            # Prefer a "round" decimal when one fits as well (0.001 rather than 0.00099999).
            for digits in range(1, 10):
                vr = float(f"{v:.{digits}g}")
                rr = pos.astype(np.float64) / vr
                if abs(vr - v) <= 1e-4 * v and np.abs(rr - np.round(rr)).max() <= 0.01:
                    return vr
            return v
    return None


def to_voxels(pos: np.ndarray, vs: float, state: str, snap: bool):
    """Integer voxel index k with k * vs the anchor's Scaffold-GS voxel position (A.7.3).
    raw: k = round(a / vs), |a - k vs| <= 1 % of vs unless --snap.
    decoded: HAC stored its 16-bit floor-quantized position a_d in (a - interval, a], so
    k = ceil(a_d / vs - 0.02), exact while the 16-bit interval is below 0.98 vs."""
    r = pos.astype(np.float64) / vs
    if state == "raw":
        k = np.round(r)
        dev = np.abs(r - k)
        worst = float(dev.max(initial=0))
        if worst > 0.01 and not snap:
            i = int(np.argmax(dev.max(axis=1)))
            raise ExportError(
                f"anchor {i} at {pos[i].tolist()} is {worst:.3f} voxels off the grid of voxel "
                f"size {vs} (anchors must lie on one voxel grid; pass --voxel-size, or --snap "
                "to round them) [A.7.3]")
        shift = r - k
    else:
        k = np.ceil(r - 0.02)
        shift = r - k  # in (-1, 0.02]: how far HAC's stored position is below the voxel
    return k.astype(np.int64), shift


def voxel_grid(pos: np.ndarray, state: str, voxel_size: float | None, cfg: dict, snap: bool, note):
    """The voxel size (`--voxel-size`, cfg_args, or inferred), the anchors' integer voxels and
    the origin (A.7.3). Returns (k, voxel size, voxel [N, 3] from 0, voxel size binary32,
    origin, coord_bits, report)."""
    vs = voxel_size
    vs_src = "--voxel-size"
    if vs is None and float(cfg.get("voxel_size", 0) or 0) > 0:
        vs, vs_src = float(cfg["voxel_size"]), "cfg_args"
    if vs is None:
        vs = infer_voxel_size(pos)
        vs_src = "inferred from the anchors"
        if vs is None:
            raise ExportError("voxel size unknown (cfg_args has voxel_size <= 0 or is missing, and "
                              "the anchors share no grid); pass --voxel-size [A.7.3]")
        if state == "decoded":
            note("voxel size inferred from decoded (16-bit quantized) positions: check it")
    if not vs > 0:
        raise ExportError("--voxel-size must be > 0 [A.7.3]")
    kk, shift = to_voxels(pos, vs, state, snap)
    kmin = kk.min(axis=0)
    vox = (kk - kmin).astype(np.int64)
    vs32 = np.float32(vs)
    origin = (kmin.astype(np.float64) * vs).astype(np.float32)
    if vox.max() > (1 << 21) - 1:
        raise ExportError(f"the anchors span {int(vox.max()) + 1} voxels of size {vs} on an axis "
                          f"(at most 2^21); pass a larger --voxel-size [§2.2 CoordinateOutOfRange]")
    bits = max(1, int(vox.max()).bit_length())
    recon = origin[None].astype(np.float64) + float(vs32) * vox
    report = {"voxel_size": float(vs32), "source": vs_src, "origin": origin.tolist(),
              "coord_bits": bits,
              "max_abs_shift_voxels": float(np.abs(shift).max(initial=0)),
              "max_position_change": float(np.abs(recon - pos).max(initial=0))}
    if state == "decoded" and float(np.abs(shift).max(initial=0)) > 0.9:
        note("decoded positions sit up to %.2f voxels below their voxel: HAC's 16-bit interval "
             "may exceed the voxel size, so some voxels may be off by one (pass --x-bound-min/"
             "--x-bound-max to check)" % float(np.abs(shift).max()))
    return kk, vs, vox, vs32, origin, bits, report


def normalization_box(kk: np.ndarray, vs: float, pos: np.ndarray, state: str,
                      x_bound_min: str | None, x_bound_max: str | None):
    """HAC's grid box (A.7.4), given or recomputed; with it given, decoded positions are checked
    against the voxels. Returns (voxel positions in the world, lo, hi, report)."""
    # -- HAC's normalization box (A.7.4): update_anchor_bound at training step 10000
    # (HAC:gaussian_renderer/__init__.py) - not saved; recomputed from the exported anchors.
    world = (kk.astype(np.float64) * vs).astype(np.float32)
    if x_bound_min or x_bound_max:
        if not (x_bound_min and x_bound_max):
            raise ExportError("--x-bound-min and --x-bound-max go together [A.7.4]")
        lo = np.array([float(s) for s in x_bound_min.split(",")], np.float32)
        hi = np.array([float(s) for s in x_bound_max.split(",")], np.float32)
        if lo.shape != (3,) or hi.shape != (3,):
            raise ExportError("--x-bound-min / --x-bound-max take three numbers x,y,z [A.7.4]")
        bsrc = "given"
        if state == "decoded":
            # With the box known, HAC's 16-bit positions can be checked against the voxels.
            q = quantize_anchor(world, lo, hi)
            bad = np.abs(q - pos).max(axis=1) > 1e-6 * max(1.0, float(np.abs(pos).max()))
            if bad.any():
                i = int(np.argmax(bad))
                raise ExportError(f"anchor {i}: voxel position {world[i].tolist()} does not "
                                  f"16-bit-quantize to the stored {pos[i].tolist()} with the given "
                                  "box (wrong --voxel-size or box?) [A.7.3]")
    else:
        lo, hi = update_anchor_bound(world)
        bsrc = "recomputed (update_anchor_bound) from the exported anchors"
    if not (hi > lo).all():
        raise ExportError(f"degenerate normalization box {lo.tolist()} .. {hi.tolist()}; pass "
                          "--x-bound-min / --x-bound-max [A.7.4]")
    return world, lo, hi, {"min": lo.tolist(), "max": hi.tolist(), "source": bsrc}
