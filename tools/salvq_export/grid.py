"""HAC's hash grids resampled onto ours (A.7.4): HAC's lookup (gridencoder.cu), ours (spec
§2.4, §5.1), the resampling, and the grid features both give at the anchors."""
from __future__ import annotations

import numpy as np

from .checkpoint import f32
from .common import PRIME_1, PRIME_2, W_BITS, ExportError
from .voxels import quantize_anchor


# ---------------------------------------------------------------------------- HAC's grids
def hac_levels(sd: dict, use_2d: bool):
    """The four GridEncoders of HAC:scene/gaussian_model.py:mix_3D2D_encoding (state-dict
    prefixes encoding_xyz., encoding_xy., encoding_xz., encoding_yz.), or the single
    GridEncoder when use_2D=False (keys params, offsets_list, resolutions_list).
    Returns {name: (params [P, C] float32, offsets [L+1] int, resolutions [L] int, d)}."""
    out = {}
    names = [("encoding_xyz.", "3d", 3), ("encoding_xy.", "xy", 2),
             ("encoding_xz.", "xz", 2), ("encoding_yz.", "yz", 2)] if use_2d else [("", "3d", 3)]
    for prefix, name, d in names:
        try:
            p = f32(sd[prefix + "params"])
            offs = sd[prefix + "offsets_list"].cpu().numpy().astype(np.int64)
            res = sd[prefix + "resolutions_list"].cpu().numpy().astype(np.int64)
        except KeyError as e:
            raise ExportError(f"checkpoint['encoding_xyz'] lacks {e} (HAC:GridEncoder) [A.7.4]") from None
        if p.ndim != 2 or offs.shape != (res.size + 1,) or offs[-1] != p.shape[0]:
            raise ExportError(f"encoding {name}: params {tuple(p.shape)} do not match "
                              f"offsets_list {offs.tolist()} [A.7.4]")
        if not np.isfinite(p).all():
            raise ExportError(f"encoding {name}: non-finite hash-grid parameter [A.7.4]")
        out[name] = (p, offs, res, d)
    return out


def hac_binarize(p: np.ndarray) -> np.ndarray:
    """HAC:utils/encodings.py:STE_binary.forward: +1 where the parameter is >= 0, else -1."""
    return np.where(p >= 0, np.float32(1), np.float32(-1))


def hac_level_eval(p: np.ndarray, emb: np.ndarray, r: int, size: int) -> np.ndarray:
    """One level of HAC:submodules/gridencoder/src/gridencoder.cu:kernel_grid (forward,
    binary_vxl = None) at normalized points p [M, d] in float32: pos = p (r - 2) + 0.5,
    corners floor(pos) and +1 (clamped to r - 1), corners on the border (0 or r - 1 on any
    axis) left out and the other weights renormalized, index dense `i + j r + k r^2` when
    r^d <= size else fast_hash, modulo size; a point outside [0, 1] gives 0.
    emb [size, C] holds the level's binarized values. Returns [M, C] float32."""
    m, d = p.shape
    c = emb.shape[1]
    p = p.astype(np.float32)
    oob = ((p < 0) | (p > 1)).any(axis=1)
    pos = p * np.float32(r - 2) + np.float32(0.5)
    pg = np.floor(pos).astype(np.int64)
    frac = (pos - pg.astype(np.float32)).astype(np.float32)
    dense = r ** d <= size
    out = np.zeros((m, c), np.float32)
    wn = np.zeros(m, np.float32)
    ws, idxs, valid = [], [], []
    for corner in range(1 << d):
        w = np.ones(m, np.float32)
        loc = np.empty((m, d), np.int64)
        for a in range(d):
            if corner & (1 << a):
                w = w * frac[:, a]
                loc[:, a] = np.minimum(pg[:, a] + 1, r - 1)
            else:
                w = w * (np.float32(1) - frac[:, a])
                loc[:, a] = pg[:, a]
        ok = ~((loc == 0) | (loc == r - 1)).any(axis=1)
        if dense:
            idx = np.zeros(m, np.int64)
            stride = 1
            for a in range(d):
                idx += loc[:, a] * stride
                stride *= r
        else:
            u = loc.astype(np.uint64)
            idx = u[:, 0] & np.uint64(0xFFFFFFFF)
            primes = [1, PRIME_1, PRIME_2]
            for a in range(1, d):
                idx = idx ^ ((u[:, a] * np.uint64(primes[a])) & np.uint64(0xFFFFFFFF))
            idx = idx.astype(np.int64)
        idx = idx % size
        wn += np.where(ok, w, np.float32(0))
        ws.append(w)
        idxs.append(idx)
        valid.append(ok)
    wn = np.where(wn == 0, np.float32(1e-9), wn)
    wre = (np.float32(1) / wn).astype(np.float32)
    for w, idx, ok in zip(ws, idxs, valid):
        out += np.where(ok, w * wre, np.float32(0))[:, None] * emb[idx]
    out[oob] = 0
    return out


def hac_level_eval_chunked(p, emb, r, size, chunk=1 << 20):
    """hac_level_eval in chunks of points, to bound memory on large scenes."""
    if len(p) <= chunk:
        return hac_level_eval(p, emb, r, size)
    return np.concatenate([hac_level_eval(p[i:i + chunk], emb, r, size)
                           for i in range(0, len(p), chunk)], axis=0)


def read_hac_grids(enc: dict, cfg: dict):
    """HAC's grids in checkpoint['encoding_xyz'] (A.7.4): the levels (hac_levels), whether the 2D
    planes are there, the channels C, and log2 of the hashed table size T of the 3D and the 2D
    levels (the hashed levels' size, else cfg_args log2 / log2_2D, else what the largest table
    needs). Returns (levels, use_2d, C, T3, T2)."""
    use_2d = any(key.startswith("encoding_xy.") for key in enc)
    levels = hac_levels(enc, use_2d)
    c = levels["3d"][0].shape[1]
    for name, (p, _, _, _) in levels.items():
        if p.shape[1] != c:
            raise ExportError(f"encoding {name}: {p.shape[1]} channels, 3D has {c} [A.7.4]")

    def log2_of(name, d, key):
        p, offs, res, _ = levels[name]
        sizes = np.diff(offs)
        hashed = [int(sz) for sz, r in zip(sizes, res) if int(r) ** d > int(sz)]
        if hashed:
            t = int(max(hashed)).bit_length() - 1
            if any(h != 1 << t for h in hashed):
                raise ExportError(f"encoding {name}: hashed levels of sizes {hashed} are not one "
                                  "power of two [A.7.4]")
            return t
        if cfg.get(key):
            return int(cfg[key])
        return max(1, int(max(sizes.max(initial=1), 2) - 1).bit_length())

    t3 = log2_of("3d", 3, "log2")
    t2 = log2_of("xy", 2, "log2_2D") if use_2d else t3
    return levels, use_2d, c, t3, t2


# ---------------------------------------------------------------------------- ours (§2.4, §5.1)
def level_entries(r: int, d: int, t: int) -> int:
    """spec §2.4: E(r, d, T) = min((r + 1)^d, 2^T)."""
    return min((r + 1) ** d, 1 << t)


def our_entry(loc: np.ndarray, r: int, t: int) -> np.ndarray:
    """spec §2.4: entry of vertex loc [M, d] on a level of resolution r."""
    d = loc.shape[1]
    if (r + 1) ** d <= (1 << t):
        idx = np.zeros(loc.shape[0], np.int64)
        stride = 1
        for a in range(d):
            idx += loc[:, a] * stride
            stride *= r + 1
        return idx
    u = loc.astype(np.uint64)
    h = u[:, 0] & np.uint64(0xFFFFFFFF)
    primes = [1, PRIME_1, PRIME_2]
    for a in range(1, d):
        h = h ^ ((u[:, a] * np.uint64(primes[a])) & np.uint64(0xFFFFFFFF))
    return (h % np.uint64(1 << t)).astype(np.int64)


def axis_weights(v: np.ndarray, r: int, bits: int):
    """spec §5.1 step 1 for coordinates v (int64): cell, w0, w1 (units 2^-10)."""
    x = (2 * v + 1) * r
    cell = x >> (bits + 1)
    frac = x & ((1 << (bits + 1)) - 1)
    w1 = frac >> (bits + 1 - W_BITS) if bits + 1 >= W_BITS else frac << (W_BITS - bits - 1)
    return cell, (1 << W_BITS) - w1, w1


def our_level_corners(vox: np.ndarray, axes, r: int, bits: int):
    """Corners (vertex coordinates [N, 2^d, d]) and float weights [N, 2^d] of spec §5.1."""
    d = len(axes)
    cw = [axis_weights(vox[:, a], r, bits) for a in axes]
    n = vox.shape[0]
    loc = np.empty((n, 1 << d, d), np.int64)
    w = np.ones((n, 1 << d), np.float64)
    for corner in range(1 << d):
        for i in range(d):
            cell, w0, w1 = cw[i]
            hi = bool(corner & (1 << i))
            loc[:, corner, i] = cell + (1 if hi else 0)
            w[:, corner] *= (w1 if hi else w0) / float(1 << W_BITS)
    return loc, w


def our_level_features(vox, axes, r, t, bits, grid_level: np.ndarray) -> np.ndarray:
    """spec §5.1 steps 2-3, exactly (integer), divided by 256: features in units of 1."""
    d = len(axes)
    cw = [axis_weights(vox[:, a], r, bits) for a in axes]
    n = vox.shape[0]
    acc = np.zeros((n, grid_level.shape[1]), np.int64)
    for corner in range(1 << d):
        loc = np.empty((n, d), np.int64)
        w = np.ones(n, np.int64)
        for i in range(d):
            cell, w0, w1 = cw[i]
            hi = bool(corner & (1 << i))
            loc[:, i] = cell + (1 if hi else 0)
            w = w * (w1 if hi else w0)
        acc += w[:, None] * grid_level[our_entry(loc, r, t)].astype(np.int64)
    s = 22 if d == 3 else 12
    return ((acc + (1 << (s - 1))) >> s).astype(np.float64) / 256.0


# ---------------------------------------------------------------------------- resampling
PLANES = {"3d": (0, 1, 2), "xy": (0, 1), "xz": (0, 2), "yz": (1, 2)}


def map_grids(levels, vox, bits, origin, vs, lo, hi, mode, t3, t2):
    """Resample HAC's binarized hash grids onto ours (A.7.4). For each of our levels, every
    touched vertex (spec §5.2) is placed in world space (p = n / r' on each axis; world =
    origin + vs (p 2^B - 1/2)), HAC's level is interpolated there by hac_level_eval (in HAC's
    normalization (x - x_bound_min) / (x_bound_max - x_bound_min)), and each of our entries
    takes the sign (>= 0: +1) of the sum of those values weighted by the weights the anchors
    give the vertex (unweighted when those weights sum to 0). Untouched entries are +1."""
    ext = (hi - lo).astype(np.float64)
    span = vs * float(1 << bits)
    gext = float(np.prod(ext)) ** (1.0 / 3.0)
    out, res_ours, info = {}, {}, []
    for name, (params, offs, res, d) in levels.items():
        emb_all = hac_binarize(params)
        t = t3 if d == 3 else t2
        axes = PLANES[name]
        tables, rs = [], []
        for li, r in enumerate(res.tolist()):
            if mode == "hac":
                rr = int(r)
            else:
                # matched: the same world-space vertex spacing as HAC's level on the
                # geometric mean of the three box extents (A.7.4).
                rr = int(round((r - 2) * span / gext))
            rr = max(1, min(65535, rr))
            rs.append(rr)
            size = int(offs[li + 1] - offs[li])
            emb = emb_all[offs[li]:offs[li + 1]]
            e = level_entries(rr, d, t)
            loc, w = our_level_corners(vox, axes, rr, bits)
            # Unique vertices by a 1-D key (coordinates <= 65536 < 2^20 per axis).
            key = np.zeros(loc.shape[0] * loc.shape[1], np.int64)
            for a in range(d):
                key |= loc[:, :, a].reshape(-1) << (20 * a)
            ukey, inv = np.unique(key, return_inverse=True)
            inv = inv.reshape(-1)
            uniq = np.stack([(ukey >> (20 * a)) & ((1 << 20) - 1) for a in range(d)], axis=1)
            world = origin[list(axes)][None, :].astype(np.float64) + vs * (
                uniq.astype(np.float64) / rr * float(1 << bits) - 0.5)
            ph = (world - lo[list(axes)][None, :]) / ext[list(axes)][None, :]
            val = hac_level_eval_chunked(ph.astype(np.float32), emb, int(r), size).astype(np.float64)
            ent = our_entry(uniq, rr, t)
            cch = emb.shape[1]
            accw = np.zeros((e, cch))
            accu = np.zeros((e, cch))
            wsum = np.zeros(e)
            vw = np.bincount(inv, weights=w.reshape(-1), minlength=uniq.shape[0])
            np.add.at(accw, ent, val * vw[:, None])
            np.add.at(accu, ent, val)
            np.add.at(wsum, ent, vw)
            acc = np.where(wsum[:, None] > 0, accw, accu)
            table = np.where(acc >= 0, 1, -1).astype(np.int8)
            tables.append(table)
            info.append({"plane": name, "level": li, "hac_resolution": int(r),
                         "hac_entries": size, "resolution": rr, "entries": e,
                         "touched": int(np.unique(ent).size)})
        out[name] = np.concatenate(tables, axis=0) if tables else np.zeros((0, 1), np.int8)
        res_ours[name] = rs
    return out, res_ours, info


def grid_contexts(levels, world, lo, hi, vox, bits, res_ours, grids, t3, t2):
    """The context MLP's inputs at every anchor: HAC's (its grids, its normalization of its
    16-bit anchor, hac_level_eval) and ours (the mapped grids, spec §5.1 exactly), [N, Cin]
    each in units of 1, and the mean absolute difference per level."""
    hac_ctx, our_ctx, per_level = [], [], []
    anchors_q = quantize_anchor(world, lo, hi)
    ph = (anchors_q.astype(np.float32) - lo[None]) / (hi - lo)[None]
    for name, (params, offs, res, d) in levels.items():
        emb_all = hac_binarize(params)
        axes = list(PLANES[name])
        tt = t3 if d == 3 else t2
        start = 0
        for li, r in enumerate(res.tolist()):
            e_h = hac_level_eval_chunked(ph[:, axes], emb_all[offs[li]:offs[li + 1]], int(r),
                                         int(offs[li + 1] - offs[li])).astype(np.float64)
            rr = res_ours[name][li]
            e = level_entries(rr, d, tt)
            e_o = our_level_features(vox, axes, rr, tt, bits, grids[name][start:start + e])
            start += e
            hac_ctx.append(e_h)
            our_ctx.append(e_o)
            per_level.append(float(np.abs(e_h - e_o).mean()))
    return np.concatenate(hac_ctx, axis=1), np.concatenate(our_ctx, axis=1), per_level
