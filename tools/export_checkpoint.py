#!/usr/bin/env python3
"""Export a HAC or SALVQ training output (the public PyTorch code) to a salvq model file.

Usage (see tools/README.md, "Exporting HAC / SALVQ checkpoints"):

    python3 tools/export_checkpoint.py RUN_DIR -o model.safetensors [--format auto|hac|salvq]
        [--iteration N] [--state auto|raw|decoded] [--voxel-size V]
        [--x-bound-min X,Y,Z --x-bound-max X,Y,Z] [--grid-resolutions matched|hac]
        [--gains G0,G1,...] [--drop-empty-anchors] [--json REPORT.json]

RUN_DIR is the training run's `model_path` (holding `cfg_args` and
`point_cloud/iteration_<N>/{point_cloud.ply,checkpoint.pth}`) or one iteration folder.
The output is the safetensors model of spec Annex A (schema 0.2), written byte-canonically
(A.1), which `salvq encode` reads. The mapping, every transform and every gap between the
two formats is spec Annex A.7; this file cites the public code it follows as
`HAC:<path>:<function>` (github.com/YihangChen-ee/HAC) and `SALVQ:<path>:<function>`
(github.com/hxu160/SALVQ, a fork of HAC that adds mlp_U, mlp_V and Gain).

Needs Python >= 3.10, numpy and torch (CPU is enough; only `torch.load`, the orthogonal
parametrization and a few float64 matrix products are used). Nothing else is imported.

Exit status: 0 on success; 2 with one line `export_checkpoint: error: ...` on stderr when the
checkpoint cannot be mapped (the message names the rule of Annex A.7 that fails).
"""
from __future__ import annotations

import argparse
import ast
import json
import math
import os
import struct
import sys
from pathlib import Path

import numpy as np

SCHEMA = "0.2"
# HAC's fixed base steps: HAC:scene/gaussian_model.py:conduct_encoding (Q_feat = 1,
# Q_scaling = 0.001, Q_offsets = 0.2; same in gaussian_renderer/__init__.py).
HAC_Q_FEAT, HAC_Q_SCALING, HAC_Q_OFFSETS = 1.0, 0.001, 0.2
# HAC:utils/encodings.py: anchor_round_digits = 16, Q_anchor = 1 / (2^16 - 1).
ANCHOR_ROUND_DIGITS = 16
# HAC:submodules/gridencoder/src/gridencoder.cu:fast_hash (the same primes as spec §2.4).
PRIME_1, PRIME_2 = 2654435761, 805459861
# spec §5.1: W = 10 weight bits.
W_BITS = 10


class ExportError(Exception):
    """A checkpoint that cannot be mapped; the message names the A.7 rule."""


# ---------------------------------------------------------------------------- input files
def locate(run_dir: Path, iteration: int | None, ply: Path | None, ckpt: Path | None):
    """Find point_cloud.ply, checkpoint.pth and cfg_args as HAC:scene/__init__.py:Scene.save
    writes them: <model_path>/point_cloud/iteration_<N>/{point_cloud.ply, checkpoint.pth}, and
    <model_path>/cfg_args (HAC:train.py:prepare_output_and_logger)."""
    run_dir = Path(run_dir)
    if (run_dir / "point_cloud.ply").exists() or (run_dir / "checkpoint.pth").exists():
        it_dir, model_path = run_dir, run_dir.parent.parent
    else:
        pc = run_dir / "point_cloud"
        if not pc.is_dir():
            raise ExportError(f"{run_dir}: neither an iteration folder (point_cloud.ply, "
                              "checkpoint.pth) nor a run folder with point_cloud/ [A.7.1]")
        iters = []
        for p in pc.iterdir():
            if p.name.startswith("iteration_") and p.name[10:].isdigit():
                iters.append(int(p.name[10:]))
        if iteration is None:
            if not iters:
                raise ExportError(f"{pc}: no iteration_<N> folder [A.7.1]")
            # HAC:utils/system_utils.py:searchForMaxIteration: the largest N.
            iteration = max(iters)
        it_dir, model_path = pc / f"iteration_{iteration}", run_dir
        if not it_dir.is_dir():
            raise ExportError(f"{it_dir}: no such iteration (have {sorted(iters)}) [A.7.1]")
    ply = Path(ply) if ply else it_dir / "point_cloud.ply"
    ckpt = Path(ckpt) if ckpt else it_dir / "checkpoint.pth"
    for p in (ply, ckpt):
        if not p.is_file():
            raise ExportError(f"{p}: missing [A.7.1]")
    cfg = model_path / "cfg_args"
    return ply, ckpt, (cfg if cfg.is_file() else None)


def read_cfg_args(path: Path | None) -> dict:
    """cfg_args is `str(Namespace(**vars(args)))` (HAC:train.py:prepare_output_and_logger);
    parsed with ast (literals only, nothing is executed)."""
    if path is None:
        return {}
    text = path.read_text().strip()
    try:
        node = ast.parse(text, mode="eval").body
        if not (isinstance(node, ast.Call) and getattr(node.func, "id", "") == "Namespace"):
            raise ValueError("not Namespace(...)")
        out = {}
        for kw in node.keywords:
            try:
                out[kw.arg] = ast.literal_eval(kw.value)
            except ValueError:
                pass  # a non-literal value: not one we use
        return out
    except (SyntaxError, ValueError) as e:
        raise ExportError(f"{path}: cannot parse cfg_args ({e}) [A.7.1]") from None


PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
    "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}


def read_ply_vertices(path: Path) -> dict[str, np.ndarray]:
    """The `vertex` element of a PLY file as {property: array}. HAC writes it with plyfile
    (HAC:scene/gaussian_model.py:save_ply): binary, one f4 property per column, no lists."""
    data = path.read_bytes()
    end = data.find(b"end_header")
    if not data.startswith(b"ply") or end < 0:
        raise ExportError(f"{path}: not a PLY file [A.7.2]")
    nl = data.find(b"\n", end)
    header = data[:end].decode("ascii", "replace").splitlines()
    body = memoryview(data)[nl + 1:]
    fmt, elements = None, []
    for line in header[1:]:
        w = line.split()
        if not w or w[0] in ("comment", "obj_info"):
            continue
        if w[0] == "format":
            fmt = w[1]
        elif w[0] == "element":
            elements.append((w[1], int(w[2]), []))
        elif w[0] == "property":
            if w[1] == "list":
                raise ExportError(f"{path}: list property '{w[-1]}' not supported [A.7.2]")
            if w[1] not in PLY_TYPES or not elements:
                raise ExportError(f"{path}: bad property line '{line}' [A.7.2]")
            elements[-1][2].append((w[2], PLY_TYPES[w[1]]))
    if fmt not in ("binary_little_endian", "binary_big_endian", "ascii"):
        raise ExportError(f"{path}: unknown PLY format {fmt} [A.7.2]")
    offset = 0
    text_rows = None
    if fmt == "ascii":
        text_rows = bytes(body).decode("ascii").split("\n")
    for name, count, props in elements:
        order = "<" if fmt == "binary_little_endian" else ">"
        dt = np.dtype([(p, order + t) for p, t in props])
        if fmt == "ascii":
            rows = [r.split() for r in text_rows[offset:offset + count]]
            offset += count
            arr = np.array([tuple(r) for r in rows], dtype=[(p, t) for p, t in props]) \
                if count else np.zeros(0, dt)
        else:
            need = dt.itemsize * count
            if offset + need > len(body):
                raise ExportError(f"{path}: truncated element '{name}' [A.7.2]")
            arr = np.frombuffer(body, dtype=dt, count=count, offset=offset)
            offset += need
        if name == "vertex":
            return {p: np.ascontiguousarray(arr[p]).astype(np.float32) for p, _ in props}
    raise ExportError(f"{path}: no 'vertex' element [A.7.2]")


def columns(v: dict, prefix: str, path) -> np.ndarray:
    """Columns `prefix<i>` sorted by i, as HAC:scene/gaussian_model.py:load_ply_sparse_gaussian
    sorts them; [N, n] float32."""
    names = [k for k in v if k.startswith(prefix) and k[len(prefix):].isdigit()]
    names.sort(key=lambda s: int(s[len(prefix):]))
    if [int(s[len(prefix):]) for s in names] != list(range(len(names))):
        raise ExportError(f"{path}: properties {prefix}* are not numbered 0..n-1 [A.7.2]")
    if not names:
        return np.zeros((len(v["x"]), 0), np.float32)
    return np.stack([v[n] for n in names], axis=1).astype(np.float32)


def load_checkpoint(path: Path) -> dict:
    import torch
    try:
        # weights_only: a state dict is tensors in dicts; nothing in it is executed.
        ck = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as e:  # noqa: BLE001 - any unpickling failure is the user's file
        raise ExportError(f"{path}: torch.load failed ({type(e).__name__}: {e}) [A.7.1]") from None
    if not isinstance(ck, dict):
        raise ExportError(f"{path}: not a dict of state dicts (HAC:save_mlp_checkpoints) [A.7.1]")
    return ck


def f32(t) -> np.ndarray:
    import torch
    return t.detach().cpu().to(dtype=torch.float32).numpy().copy()


# ---------------------------------------------------------------------------- positions
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


# ---------------------------------------------------------------------------- hash grids
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


# ---------------------------------------------------------------------------- SALVQ basis
def orthogonal_weight(sd: dict, f: int, key: str) -> np.ndarray:
    """The weight SALVQ uses: SALVQ:scene/gaussian_model.py registers
    P.orthogonal(nn.Linear(feat_dim, feat_dim, bias=False)); its state dict holds
    parametrizations.weight.original and parametrizations.weight.0.base. Loading it into the
    same module and reading .weight runs PyTorch's own map (base @ matrix_exp(A)), so the
    matrix is the one training used (up to CPU vs GPU rounding). A plain 'weight' (a model
    whose parametrization was removed) is taken as it is."""
    import torch
    import torch.nn as nn
    import torch.nn.utils.parametrizations as P
    if "weight" in sd and not any(k.startswith("parametrizations.") for k in sd):
        w = f32(sd["weight"])
    else:
        m = P.orthogonal(nn.Linear(f, f, bias=False))
        try:
            m.load_state_dict(sd)
        except Exception as e:  # noqa: BLE001
            raise ExportError(f"checkpoint['{key}']: not the state dict of "
                              f"P.orthogonal(nn.Linear({f}, {f}, bias=False)) ({e}) [A.7.6]") from None
        with torch.no_grad():
            w = f32(m.weight)
    if w.shape != (f, f):
        raise ExportError(f"checkpoint['{key}']: weight {w.shape}, expected ({f}, {f}) [A.7.6]")
    err = float(np.abs(w.astype(np.float64) @ w.T.astype(np.float64) - np.eye(f)).max())
    if err > 1e-3:
        raise ExportError(f"checkpoint['{key}']: weight is not orthogonal (|W W^T - I| = {err:.2e} "
                          "> 1e-3, spec §2.6 BasisNotOrthogonal) [A.7.6]")
    return w


def salvq_basis(ck: dict, f: int, t: dict):
    """A.7.6. SALVQ decodes x = ((Q u) W_U / g) W_V + mu (row vectors;
    SALVQ:scene/gaussian_model.py:conduct_decoding, gaussian_renderer/__init__.py), that is
    x = mu + Q (W_V^T diag(1/g) W_U^T) u, so B = U diag(s) V^T with U = W_V^T, s = 1/g, V = W_U.
    Fills the basis tensors of t; returns (W_U, g, W_V) and a report."""
    wu = orthogonal_weight(ck["mlp_U"], f, "mlp_U")
    wv = orthogonal_weight(ck["mlp_V"], f, "mlp_V")
    g = f32(ck["gain"]).reshape(-1)
    if g.shape != (f,):
        raise ExportError(f"checkpoint['gain']: shape {tuple(ck['gain'].shape)}, "
                          f"expected [1, {f}] [A.7.6]")
    if (g == 0).any() or not np.isfinite(g).all():
        raise ExportError("checkpoint['gain']: a zero or non-finite gain (s = 1/gain) [A.7.6]")
    t["quant.feat.basis_u"] = np.ascontiguousarray(wv.T).astype(np.float32)
    t["quant.feat.basis_s"] = (1.0 / g.astype(np.float64)).astype(np.float32)
    t["quant.feat.basis_v"] = np.ascontiguousarray(wu).astype(np.float32)
    rep = {"orthogonality_U": float(np.abs(wv.astype(np.float64).T @ wv - np.eye(f)).max()),
           "orthogonality_V": float(np.abs(wu.astype(np.float64).T @ wu - np.eye(f)).max()),
           "gain_min": float(np.abs(g).min()), "gain_max": float(np.abs(g).max()),
           "condition": float(np.abs(g).max() / np.abs(g).min())}
    return (wu, g, wv), rep


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


# ---------------------------------------------------------------------------- estimates
def estimate_bits(ctx, mlp, feat, scal, offs, mask, f, k, basis=None):
    """HAC's own estimate of the coded bits (HAC:scene/gaussian_model.py:estimate_final_bits,
    HAC:utils/entropy_models.py:Entropy_gaussian with Low_bound 1e-6) of the three attribute
    groups given grid features ctx [N, Cin]; with basis (SALVQ) the features are coded as in
    SALVQ:scene/gaussian_model.py:estimate_final_bits (mean removed, V, Gain, U, zero mean)."""
    import torch
    if len(ctx) > 32768:   # in chunks, to bound memory on large scenes
        parts = [estimate_bits(ctx[i:i + 32768], mlp, feat[i:i + 32768], scal[i:i + 32768],
                               offs[i:i + 32768], mask[i:i + 32768], f, k, basis)
                 for i in range(0, len(ctx), 32768)]
        return tuple(float(sum(p[j] for p in parts)) for j in range(3))
    d = torch.float64
    x = torch.from_numpy(ctx).to(d)
    w0, b0, w1, b1 = (torch.from_numpy(mlp[n].astype(np.float64)) for n in
                      ("mlp_grid.0.weight", "mlp_grid.0.bias", "mlp_grid.2.weight", "mlp_grid.2.bias"))
    out = torch.relu(x @ w0.T + b0) @ w1.T + b1
    mu, sc, mus, scs, muo, sco, af, as_, ao = torch.split(
        out, [f, f, 6, 6, 3 * k, 3 * k, 1, 1, 1], dim=-1)

    def bits(v, m, s, q):
        s = torch.clamp(s, min=1e-9)
        vq = torch.round(v / q) * q
        n = torch.distributions.Normal(m, s)
        p = torch.clamp(torch.abs(n.cdf(vq + 0.5 * q) - n.cdf(vq - 0.5 * q)), min=1e-6)
        return -torch.log2(p)

    qf = HAC_Q_FEAT * (1 + torch.tanh(af))
    fe = torch.from_numpy(feat).to(d)
    if basis is None:
        bf = bits(fe, mu, sc, qf).sum()
    else:
        wu, g, wv = (torch.from_numpy(a.astype(np.float64)) for a in basis)
        y = (((fe - mu) @ wv.T) * g) @ wu.T
        bf = bits(y, torch.zeros_like(y), sc, qf).sum()
    bs = bits(torch.from_numpy(scal).to(d), mus, scs, HAC_Q_SCALING * (1 + torch.tanh(as_))).sum()
    o = torch.from_numpy(offs.reshape(len(offs), -1)).to(d)
    mk = torch.from_numpy(np.repeat(mask, 3, axis=1).astype(np.float64))
    bo = (bits(o, muo, sco, HAC_Q_OFFSETS * (1 + torch.tanh(ao))) * mk).sum()
    return float(bf), float(bs), float(bo)


# ---------------------------------------------------------------------------- output
TABLE_ORDER = [
    "geometry.origin", "geometry.voxel_size", "anchor.voxel", "anchor.mask", "anchor.feat",
    "anchor.scaling", "anchor.offsets", "hyperprior.resolutions_3d",
    "hyperprior.resolutions_2d", "hyperprior.log2_size", "hyperprior.grid_3d",
    "hyperprior.grid_xy", "hyperprior.grid_xz", "hyperprior.grid_yz",
    "mlp_grid.0.weight", "mlp_grid.0.bias", "mlp_grid.2.weight", "mlp_grid.2.bias",
] + [f"{m}.{l}.{p}" for m in ("mlp_opacity", "mlp_cov", "mlp_color")
     for l in (0, 2) for p in ("weight", "bias")] + [
    "quant.feat.step", "quant.feat.gains", "quant.feat.basis_u", "quant.feat.basis_s",
    "quant.feat.basis_v", "quant.scaling.step", "quant.scaling.gains", "quant.offsets.step",
    "quant.offsets.gains",
]
DTYPES = {np.dtype(np.float32): "F32", np.dtype(np.int32): "I32", np.dtype(np.uint8): "U8",
          np.dtype(np.int8): "I8"}


def write_safetensors(path: Path, tensors: dict, feat_lattice: str) -> int:
    """spec Annex A.1, byte-canonical: compact JSON header (metadata, then Table 2-1 order),
    data contiguous in that order, header padded with spaces to a multiple of 8. Written to a
    temporary file in the same folder and renamed (no partial output)."""
    meta = {"format": "salvq-model", "schema": SCHEMA, "feat_lattice": feat_lattice,
            "scaling_lattice": "identity"}
    header = {"__metadata__": meta}
    blobs, off = [], 0
    for name in TABLE_ORDER:
        if name not in tensors:
            continue
        a = np.ascontiguousarray(tensors[name])
        raw = a.astype(a.dtype.newbyteorder("<"), copy=False).tobytes()
        header[name] = {"dtype": DTYPES[a.dtype], "shape": list(a.shape),
                        "data_offsets": [off, off + len(raw)]}
        blobs.append(raw)
        off += len(raw)
    h = json.dumps(header, separators=(",", ":")).encode()
    h += b" " * (-len(h) % 8)
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    try:
        with open(tmp, "wb") as fh:
            fh.write(struct.pack("<Q", len(h)))
            fh.write(h)
            for b in blobs:
                fh.write(b)
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()
    return 8 + len(h) + off


def validate(t: dict):
    """The value rules of spec §2.3 / §2.6 / Annex A.2 step 4-5 that a checkpoint can break,
    checked here so that the message names the checkpoint's tensor."""
    for name in TABLE_ORDER:
        a = t.get(name)
        if a is None:
            continue
        if a.dtype == np.float32 and not np.isfinite(a).all():
            i = np.argwhere(~np.isfinite(a))[0].tolist()
            raise ExportError(f"{name}{i}: value is not finite [§2.3]")
    v = t["anchor.voxel"]
    if v.min(initial=0) < 0 or v.max(initial=0) > (1 << 21) - 1:
        raise ExportError("anchor.voxel: the anchors span more than 2^21 voxels on an axis; "
                          "pass a larger --voxel-size [§2.3 CoordinateOutOfRange]")
    for name in ("geometry.voxel_size", "quant.feat.step", "quant.feat.gains",
                 "quant.scaling.step", "quant.scaling.gains", "quant.offsets.step",
                 "quant.offsets.gains"):
        if (t[name] <= 0).any():
            raise ExportError(f"{name}: value not > 0 [§2.3 ValueNotPositive]")
    if "quant.feat.basis_s" in t:
        s = np.abs(t["quant.feat.basis_s"].astype(np.float64))
        if (s == 0).any():
            raise ExportError("quant.feat.basis_s: a zero (SALVQ Gain infinite) [§2.6 BasisSingular]")
        cond = s.max() / s.min()
        if cond > 1e6:
            raise ExportError(f"quant.feat.basis_s: condition number {cond:.3g} > 1e6 "
                              "(SALVQ Gain spans too wide a range) [§2.6 BasisIllConditioned]")


# ---------------------------------------------------------------------------- main
def export(args) -> dict:
    import torch
    torch.set_grad_enabled(False)
    ply, ckpt_path, cfg_path = locate(args.run_dir, args.iteration, args.ply, args.checkpoint)
    cfg = read_cfg_args(cfg_path)
    ck = load_checkpoint(ckpt_path)
    rep = {"ply": str(ply), "checkpoint": str(ckpt_path), "cfg_args": str(cfg_path) if cfg_path else None,
           "notes": []}
    note = rep["notes"].append

    # -- format (A.7.1): SALVQ:scene/gaussian_model.py:save_mlp_checkpoints adds mlp_U, mlp_V, gain.
    is_salvq = all(k in ck for k in ("mlp_U", "mlp_V", "gain"))
    fmt = args.format
    if fmt == "auto":
        fmt = "salvq" if is_salvq else "hac"
    if fmt == "salvq" and not is_salvq:
        raise ExportError("--format salvq: the checkpoint has no mlp_U / mlp_V / gain [A.7.1]")
    if fmt == "hac" and is_salvq:
        note("the checkpoint is SALVQ's; --format hac exports it as USQ, ignoring mlp_U, mlp_V, gain")
    for key in ("opacity_mlp", "cov_mlp", "color_mlp", "encoding_xyz", "grid_mlp"):
        if key not in ck:
            raise ExportError(f"{ckpt_path}: no '{key}' (HAC:save_mlp_checkpoints keys) [A.7.1]")
    if "mlp_feature_bank" in ck or cfg.get("use_feat_bank"):
        raise ExportError("use_feat_bank=True: the view-dependent feature bank (mlp_feature_bank) "
                          "has no tensor in the format [A.7.7]")
    rep["format"] = fmt

    # -- PLY (A.7.2): HAC:scene/gaussian_model.py:save_ply / construct_list_of_attributes.
    v = read_ply_vertices(ply)
    for c in ("x", "y", "z"):
        if c not in v:
            raise ExportError(f"{ply}: no property {c} [A.7.2]")
    pos = np.stack([v["x"], v["y"], v["z"]], axis=1).astype(np.float32)
    feat = columns(v, "f_anchor_feat_", ply)
    off_flat = columns(v, "f_offset_", ply)
    mask_raw = columns(v, "f_mask_", ply)
    scale_raw = columns(v, "scale_", ply)
    n_all, f = feat.shape
    k = mask_raw.shape[1]
    s_dim = scale_raw.shape[1]
    if f == 0 or k == 0 or s_dim == 0:
        raise ExportError(f"{ply}: needs f_anchor_feat_*, f_mask_* and scale_* properties [A.7.2]")
    if off_flat.shape[1] != 3 * k:
        raise ExportError(f"{ply}: {off_flat.shape[1]} f_offset_* for {k} f_mask_* (want 3K) [A.7.2]")
    # save_ply writes _offset [N, K, 3] as transpose(1, 2).flatten: column c*K + k is
    # coordinate c of offset k (load_ply_sparse_gaussian reshapes (N, 3, K), transposes back).
    offsets = off_flat.reshape(n_all, 3, k).transpose(0, 2, 1).copy()
    for name, arr in (("position", pos), ("f_anchor_feat", feat), ("f_offset", off_flat),
                      ("f_mask", mask_raw), ("scale", scale_raw)):
        if not np.isfinite(arr).all():
            i = int(np.argwhere(~np.isfinite(arr))[0][0])
            raise ExportError(f"{ply}: anchor {i}: {name} is not finite [A.7.2]")

    # Columns Scaffold-GS rendering does not read (HAC:gaussian_renderer/__init__.py:
    # generate_neural_gaussians uses anchor, feat, offsets, scaling, masks; prefilter_voxel
    # culls with the anchor's scaling and rotation, which stays the identity it is created with).
    rot = columns(v, "rot_", ply)
    ident = float((np.abs(rot - np.array([1, 0, 0, 0], np.float32)).max(axis=1) < 1e-6).mean()) \
        if rot.shape[1] == 4 else float("nan")
    note("not exported (no tensor in the format, not used to render): nx ny nz, opacity, rot_* "
         f"({100 * ident:.1f} % of the rotations are the identity)")

    # -- state (A.7.2): HAC:train.py calls training_report (which, with run_codec = True, runs
    # conduct_encoding + conduct_decoding and sets decoded_version) before scene.save at the
    # last test iteration, so the default run saves the *decoded* model.
    binary_masks = bool(np.isin(mask_raw, (0.0, 1.0)).all())
    state = args.state
    if state == "auto":
        if not binary_masks or (scale_raw < 0).any():
            state = "raw"
        else:
            state = "decoded"
            note("state auto -> decoded: masks are all 0/1 and no scale is negative (a raw "
                 "model stores mask logits and log-scales); pass --state raw to override")
    if state == "decoded" and not binary_masks:
        raise ExportError("--state decoded: f_mask_* values other than 0 and 1 [A.7.2]")
    rep["state"] = state
    if state == "raw":
        # HAC:GaussianModel.get_mask: sigmoid(_mask) > 0.01; get_scaling: exp(_scaling).
        mask = (torch.sigmoid(torch.from_numpy(mask_raw)) > 0.01).numpy().astype(np.uint8)
        scaling = torch.exp(torch.from_numpy(scale_raw)).numpy().astype(np.float32)
    else:
        # decoded_version: _mask holds 0/1, _scaling the (decoded) activated scaling.
        mask = mask_raw.astype(np.uint8)
        scaling = scale_raw.astype(np.float32)
    if not np.isfinite(scaling).all():
        raise ExportError("exp(scale_*) overflows binary32 [A.7.2]")

    keep = np.ones(n_all, bool)
    empty = mask.sum(axis=1) == 0
    if state == "decoded":
        # conduct_decoding fills anchors n .. N_full-1 (those whose masks were all 0, which
        # conduct_encoding dropped) with zeros: they are not anchors of the coded scene.
        keep &= ~empty
        if empty.any():
            note(f"dropped {int(empty.sum())} zero-filled anchors (all-zero mask) that HAC's "
                 "conduct_decoding appends")
    elif args.drop_empty_anchors:
        keep &= ~empty
        note(f"--drop-empty-anchors: dropped {int(empty.sum())} anchors with an all-zero mask "
             "(HAC:conduct_encoding drops them too; they spawn no Gaussian)")
    if not keep.any():
        raise ExportError("no anchor left (every mask is all zero) [A.7.2]")
    pos, feat, offsets, mask, scaling = pos[keep], feat[keep], offsets[keep], mask[keep], scaling[keep]
    n = int(pos.shape[0])
    rep["anchors"] = {"in_ply": n_all, "exported": n, "with_empty_mask": int((mask.sum(1) == 0).sum())}

    # -- voxel grid (A.7.3).
    vs = args.voxel_size
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
    kk, shift = to_voxels(pos, vs, state, args.snap)
    kmin = kk.min(axis=0)
    vox = (kk - kmin).astype(np.int64)
    vs32 = np.float32(vs)
    origin = (kmin.astype(np.float64) * vs).astype(np.float32)
    if vox.max() > (1 << 21) - 1:
        raise ExportError(f"the anchors span {int(vox.max()) + 1} voxels of size {vs} on an axis "
                          f"(at most 2^21); pass a larger --voxel-size [§2.2 CoordinateOutOfRange]")
    bits = max(1, int(vox.max()).bit_length())
    recon = origin[None].astype(np.float64) + float(vs32) * vox
    rep["voxels"] = {"voxel_size": float(vs32), "source": vs_src, "origin": origin.tolist(),
                     "coord_bits": bits,
                     "max_abs_shift_voxels": float(np.abs(shift).max(initial=0)),
                     "max_position_change": float(np.abs(recon - pos).max(initial=0))}
    if state == "decoded" and float(np.abs(shift).max(initial=0)) > 0.9:
        note("decoded positions sit up to %.2f voxels below their voxel: HAC's 16-bit interval "
             "may exceed the voxel size, so some voxels may be off by one (pass --x-bound-min/"
             "--x-bound-max to check)" % float(np.abs(shift).max()))

    # -- HAC's normalization box (A.7.4): update_anchor_bound at training step 10000
    # (HAC:gaussian_renderer/__init__.py) - not saved; recomputed from the exported anchors.
    world = (kk.astype(np.float64) * vs).astype(np.float32)
    if args.x_bound_min or args.x_bound_max:
        if not (args.x_bound_min and args.x_bound_max):
            raise ExportError("--x-bound-min and --x-bound-max go together [A.7.4]")
        lo = np.array([float(s) for s in args.x_bound_min.split(",")], np.float32)
        hi = np.array([float(s) for s in args.x_bound_max.split(",")], np.float32)
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
    rep["x_bound"] = {"min": lo.tolist(), "max": hi.tolist(), "source": bsrc}

    # -- hash grids (A.7.4).
    enc = ck["encoding_xyz"]
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
    grids, res_ours, grid_info = map_grids(levels, vox, bits, origin.astype(np.float64),
                                           float(vs32), lo.astype(np.float64),
                                           hi.astype(np.float64), args.grid_resolutions, t3, t2)
    l3 = len(res_ours["3d"])
    l2 = len(res_ours.get("xy", []))
    cin = c * (l3 + 3 * l2)

    # -- MLPs (A.7.5): HAC:GaussianModel.__init__ nn.Sequential(Linear, ReLU, Linear[, act]).
    t = {}
    pairs = [("grid_mlp", "mlp_grid"), ("opacity_mlp", "mlp_opacity"), ("cov_mlp", "mlp_cov"),
             ("color_mlp", "mlp_color")]
    for src, dst in pairs:
        sd = ck[src]
        for key in ("0.weight", "0.bias", "2.weight", "2.bias"):
            if key not in sd:
                raise ExportError(f"checkpoint['{src}'] has no '{key}' (keys {sorted(sd)}) [A.7.5]")
            t[f"{dst}.{key}"] = f32(sd[key])
        extra = sorted(set(sd) - {"0.weight", "0.bias", "2.weight", "2.bias"})
        if extra:
            raise ExportError(f"checkpoint['{src}'] has layers beyond Linear-ReLU-Linear: {extra} [A.7.5]")
    h = t["mlp_grid.0.weight"].shape[0]
    cout = 2 * (f + s_dim + 3 * k) + 3
    hs, fin = t["mlp_opacity.0.weight"].shape
    vdim = fin - f
    want = {
        "mlp_grid.0.weight": (h, cin), "mlp_grid.0.bias": (h,), "mlp_grid.2.weight": (cout, h),
        "mlp_grid.2.bias": (cout,),
        "mlp_opacity.0.weight": (hs, f + vdim), "mlp_opacity.0.bias": (hs,),
        "mlp_opacity.2.weight": (k, hs), "mlp_opacity.2.bias": (k,),
        "mlp_cov.0.weight": (hs, f + vdim), "mlp_cov.0.bias": (hs,),
        "mlp_cov.2.weight": (7 * k, hs), "mlp_cov.2.bias": (7 * k,),
        "mlp_color.0.weight": (hs, f + vdim), "mlp_color.0.bias": (hs,),
        "mlp_color.2.weight": (3 * k, hs), "mlp_color.2.bias": (3 * k,),
    }
    for name, shp in want.items():
        if t[name].shape != shp:
            raise ExportError(f"{name}: shape {t[name].shape}, expected {shp} for F={f}, K={k}, "
                              f"S={s_dim}, Cin={cin} [A.7.5]")
    if s_dim != 6:
        note(f"{s_dim} scaling dimensions (HAC has 6)")
    if vdim < 0 or vdim > 8:
        raise ExportError(f"Scaffold-GS MLP input {fin} - F = {vdim} view inputs (0..8) [A.7.5]")
    if "deform_mlp" in ck:
        note("deform_mlp is saved but never used for rendering or coding (HAC excludes it from "
             "get_mlp_size); not exported")

    # -- tensors (Table 2-1).
    t["geometry.origin"] = origin
    t["geometry.voxel_size"] = np.array([vs32], np.float32)
    t["anchor.voxel"] = vox.astype(np.int32)
    t["anchor.mask"] = mask.astype(np.uint8)
    t["anchor.feat"] = feat.astype(np.float32)
    t["anchor.scaling"] = scaling.astype(np.float32)
    t["anchor.offsets"] = offsets.astype(np.float32)
    t["hyperprior.resolutions_3d"] = np.array(res_ours["3d"], np.int32)
    t["hyperprior.resolutions_2d"] = np.array(res_ours.get("xy", []), np.int32)
    t["hyperprior.log2_size"] = np.array([t3, t2], np.int32)
    t["hyperprior.grid_3d"] = grids["3d"]
    for pl in ("xy", "xz", "yz"):
        t[f"hyperprior.grid_{pl}"] = grids.get(pl, np.zeros((0, c), np.int8))
    gains = np.array([float(g) for g in args.gains.split(",")], np.float32)
    for grp, q in (("feat", HAC_Q_FEAT), ("scaling", HAC_Q_SCALING), ("offsets", HAC_Q_OFFSETS)):
        t[f"quant.{grp}.step"] = np.array([q], np.float32)
        t[f"quant.{grp}.gains"] = gains
    basis = None
    lattice = "identity"
    if fmt == "salvq":
        basis, rep["salvq"] = salvq_basis(ck, f, t)
        lattice = "basis"
    validate(t)

    # -- what the grid mapping costs (A.7.4): HAC's own context vs ours, same MLP.
    hac_ctx, our_ctx, per_level = grid_contexts(levels, world, lo, hi, vox, bits, res_ours,
                                                grids, t3, t2)
    mlp = {n: t[n] for n in ("mlp_grid.0.weight", "mlp_grid.0.bias", "mlp_grid.2.weight",
                             "mlp_grid.2.bias")}
    if s_dim == 6:
        b_h = estimate_bits(hac_ctx, mlp, feat, scaling, offsets, mask, f, k, basis)
        b_o = estimate_bits(our_ctx, mlp, feat, scaling, offsets, mask, f, k, basis)
    else:
        b_h = b_o = (float("nan"),) * 3
    rep["grid"] = {"mode": args.grid_resolutions, "log2_size": [t3, t2], "channels": c,
                   "levels": grid_info,
                   "mean_abs_feature_difference": float(np.abs(hac_ctx - our_ctx).mean()),
                   "mean_abs_feature_difference_per_level": per_level,
                   "sign_agreement": float((np.sign(hac_ctx) == np.sign(our_ctx)).mean())}
    rep["estimated_bits_hac_context"] = dict(zip(("feat", "scaling", "offsets"), b_h))
    rep["estimated_bits_mapped_context"] = dict(zip(("feat", "scaling", "offsets"), b_o))
    rep["dims"] = {"N": n, "F": f, "K": k, "S": s_dim, "M": int(gains.size), "C": c, "L3": l3,
                   "L2": l2, "H": h, "Hs": hs, "V": vdim, "Cin": cin, "Cout": cout}
    rep["lattice"] = lattice
    rep["tensors"] = t
    return rep


def summary(rep: dict) -> str:
    d = rep["dims"]
    lines = [
        f"format {rep['format']} ({rep['state']} state); {rep['anchors']['exported']} anchors "
        f"exported of {rep['anchors']['in_ply']} in the PLY "
        f"({rep['anchors']['with_empty_mask']} with an all-zero mask)",
        "dims: " + ", ".join(f"{k_}={v_}" for k_, v_ in d.items()),
        f"voxel size {rep['voxels']['voxel_size']:g} ({rep['voxels']['source']}), origin "
        f"{[round(x, 6) for x in rep['voxels']['origin']]}, coord_bits {rep['voxels']['coord_bits']}, "
        f"largest position change {rep['voxels']['max_position_change']:.3g}",
        f"HAC box {[round(x, 6) for x in rep['x_bound']['min']]} .. "
        f"{[round(x, 6) for x in rep['x_bound']['max']]} ({rep['x_bound']['source']})",
    ]
    g = rep["grid"]
    res3 = [lv["resolution"] for lv in g["levels"] if lv["plane"] == "3d"]
    res2 = [lv["resolution"] for lv in g["levels"] if lv["plane"] == "xy"]
    lines.append(f"hash grid ({g['mode']} resolutions): 3D {res3}, 2D {res2}, log2 {g['log2_size']}; "
                 f"mean |HAC feature - ours| at the anchors {g['mean_abs_feature_difference']:.3f}, "
                 f"same sign {100 * g['sign_agreement']:.1f} %")
    bh, bo = rep["estimated_bits_hac_context"], rep["estimated_bits_mapped_context"]
    parts = []
    for key in ("feat", "scaling", "offsets"):
        if bh[key] == bh[key] and bh[key] > 0:
            parts.append(f"{key} {bh[key] / 8:.0f} -> {bo[key] / 8:.0f} B ({100 * (bo[key] / bh[key] - 1):+.1f} %)")
    if parts:
        lines.append("HAC's float estimate of the symbol bytes, its own grid context -> the mapped "
                     "grid: " + ", ".join(parts))
    if "salvq" in rep:
        s = rep["salvq"]
        lines.append(f"SALVQ basis: |U^T U - I| {s['orthogonality_U']:.1e}, |V^T V - I| "
                     f"{s['orthogonality_V']:.1e}, gain {s['gain_min']:.4g} .. {s['gain_max']:.4g} "
                     f"(condition {s['condition']:.3g})")
    for nt in rep["notes"]:
        lines.append("note: " + nt)
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("run_dir", type=Path, help="run folder (model_path) or one iteration folder")
    ap.add_argument("-o", "--output", type=Path, required=True, help="output model (safetensors)")
    ap.add_argument("--format", choices=("auto", "hac", "salvq"), default="auto",
                    help="auto: salvq when the checkpoint has mlp_U, mlp_V and gain")
    ap.add_argument("--iteration", type=int, help="point_cloud/iteration_<N> (default: the largest)")
    ap.add_argument("--ply", type=Path, help="anchor PLY (default: <iteration>/point_cloud.ply)")
    ap.add_argument("--checkpoint", type=Path, help="MLP checkpoint (default: <iteration>/checkpoint.pth)")
    ap.add_argument("--state", choices=("auto", "raw", "decoded"), default="auto",
                    help="raw: PLY holds mask logits and log-scales; decoded: HAC's codec ran "
                         "before saving (run_codec=True, the default) (A.7.2)")
    ap.add_argument("--voxel-size", type=float, help="default: cfg_args voxel_size, else inferred")
    ap.add_argument("--snap", action="store_true", help="round off-grid anchors to the voxel grid")
    ap.add_argument("--x-bound-min", help="HAC's x_bound_min x,y,z (default: recomputed); "
                    "write --x-bound-min=-1.2,0.5,3 when it starts with a minus")
    ap.add_argument("--x-bound-max", help="HAC's x_bound_max x,y,z (default: recomputed)")
    ap.add_argument("--grid-resolutions", choices=("matched", "hac"), default="matched",
                    help="matched: our level resolutions give HAC's world-space vertex spacing; "
                         "hac: HAC's numbers verbatim (A.7.4)")
    ap.add_argument("--gains", default="1", help="per-rate gains, e.g. 1,1.5,2 (default 1)")
    ap.add_argument("--drop-empty-anchors", action="store_true",
                    help="drop anchors whose masks are all zero (as HAC's codec does)")
    ap.add_argument("--json", type=Path, help="also write the report as JSON")
    args = ap.parse_args(argv)
    try:
        try:
            gains = [float(x) for x in args.gains.split(",")]
        except ValueError:
            raise ExportError(f"--gains {args.gains!r}: not a list of numbers") from None
        if not gains or not all(math.isfinite(x) and x > 0 for x in gains) or len(gains) > 64:
            raise ExportError("--gains: 1 to 64 finite values > 0 [§2.3]")
        rep = export(args)
        nbytes = write_safetensors(args.output, rep["tensors"], rep["lattice"])
    except ExportError as e:
        print(f"export_checkpoint: error: {e}", file=sys.stderr)
        return 2
    print(summary(rep))
    print(f"wrote {args.output} ({nbytes} bytes, feat lattice {rep['lattice']})")
    if args.json:
        out = {k_: v_ for k_, v_ in rep.items() if k_ != "tensors"}
        args.json.write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
