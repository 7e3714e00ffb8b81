"""A training output like the public code's (A.7.1): the checkpoint (HAC's state-dict keys and
shapes, SALVQ's orthogonal parametrizations and gain), the anchor PLY in the raw or the decoded
state, and cfg_args, made with torch on the CPU; and what the test compares the export with."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import torch
import torch.nn as nn
import torch.nn.utils.parametrizations as P

HAC_RES_3D = (18, 24, 33, 44, 59, 80, 108, 148, 201, 275, 376, 514)   # HAC GaussianModel defaults
HAC_RES_2D = (130, 258, 514, 1026)


class GridEncoderLike(nn.Module):
    """Same parameters and buffers as HAC:utils/encodings.py:GridEncoder.__init__ (no CUDA)."""

    def __init__(self, num_dim, n_features, resolutions_list, log2_hashmap_size):
        super().__init__()
        res = torch.tensor(resolutions_list).to(torch.int)
        offsets, off = [], 0
        for r in res.tolist():
            p = min(2 ** log2_hashmap_size, r ** num_dim)
            p = int(np.ceil(p / 8) * 8)
            offsets.append(off)
            off += p
        offsets.append(off)
        self.register_buffer("offsets_list", torch.from_numpy(np.array(offsets, dtype=np.int32)))
        self.register_buffer("resolutions_list", res)
        self.params = nn.Parameter(torch.empty(off, n_features))


class Mix3D2D(nn.Module):
    """State-dict layout of HAC:scene/gaussian_model.py:mix_3D2D_encoding."""

    def __init__(self, c, res3, t3, res2, t2):
        super().__init__()
        self.encoding_xyz = GridEncoderLike(3, c, res3, t3)
        self.encoding_xy = GridEncoderLike(2, c, res2, t2)
        self.encoding_xz = GridEncoderLike(2, c, res2, t2)
        self.encoding_yz = GridEncoderLike(2, c, res2, t2)


def hac_bound(a: torch.Tensor):
    """HAC:scene/gaussian_model.py:update_anchor_bound."""
    lo = torch.min(a, dim=0, keepdim=True)[0]
    hi = torch.max(a, dim=0, keepdim=True)[0]
    for c in range(3):
        lo[0, c] = lo[0, c] * 1.2 if lo[0, c] < 0 else lo[0, c] * 0.8
        hi[0, c] = hi[0, c] * 1.2 if hi[0, c] > 0 else hi[0, c] * 0.8
    return lo, hi


def hac_quantize(a, lo, hi):
    """HAC:utils/encodings.py:Quantize_anchor.forward."""
    interval = (hi - lo) * (1 / (2 ** 16 - 1)) + 1e-6
    q = torch.clamp(torch.div(a - lo, interval, rounding_mode="floor"), 0, 2 ** 16 - 1)
    return q * interval + lo, interval


def fill_smooth_grid(enc: GridEncoderLike, axes, lo, hi, rng, raw):
    """Trained-looking parameters: on dense levels a smooth field of the vertex's world
    position (HAC vertex n sits at p = (n - 0.5) / (r - 2), gridencoder.cu), elsewhere noise."""
    offs = enc.offsets_list.tolist()
    res = enc.resolutions_list.tolist()
    d = len(axes)
    c = enc.params.shape[1]
    out = np.empty(tuple(enc.params.shape), np.float32)
    freq = rng.normal(size=(c, 3)) * 2.0
    phase = rng.uniform(0, 2 * np.pi, c)
    for li, r in enumerate(res):
        size = offs[li + 1] - offs[li]
        if r ** d <= size:
            n = np.stack(np.meshgrid(*[np.arange(r)] * d, indexing="ij"), -1).reshape(-1, d)
            # HAC's dense index is i + j r + k r^2: axis 0 fastest.
            idx = np.zeros(len(n), np.int64)
            for a in range(d):
                idx += n[:, a] * r ** a
            world = lo[axes][None] + (n - 0.5) / (r - 2) * (hi - lo)[axes][None]
            w3 = np.zeros((len(n), 3))
            w3[:, axes] = world
            val = np.sin(w3 @ freq.T * (0.4 + 0.2 * li) + phase[None])
            tab = rng.normal(size=(size, c)).astype(np.float32)
            tab[idx] = val
        else:
            tab = rng.normal(size=(size, c)).astype(np.float32)
        out[offs[li]:offs[li + 1]] = tab if raw else np.where(tab >= 0, 1.0, -1.0)
    with torch.no_grad():
        enc.params.copy_(torch.from_numpy(out))


def write_ply(path: Path, names, data: np.ndarray):
    """As HAC:scene/gaussian_model.py:save_ply (plyfile, one f4 per attribute)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        from plyfile import PlyData, PlyElement
        el = np.empty(data.shape[0], dtype=[(a, "f4") for a in names])
        el[:] = list(map(tuple, data))
        PlyData([PlyElement.describe(el, "vertex")]).write(str(path))
    except ImportError:  # the same bytes plyfile writes
        head = "ply\nformat binary_little_endian 1.0\nelement vertex %d\n" % data.shape[0]
        head += "".join(f"property float {a}\n" for a in names) + "end_header\n"
        path.write_bytes(head.encode() + data.astype("<f4").tobytes())


def make_run(root: Path, *, salvq: bool, decoded: bool, use_2d: bool, n_target: int, seed: int,
             f=50, k=10, c=4, vs=0.01, t3=13, t2=15, res3=HAC_RES_3D, res2=HAC_RES_2D,
             feature_bank=False, iteration=30000, cfg_vs=None):
    """A training output as the public code writes it; returns what the test compares with."""
    rng = np.random.default_rng(seed)
    torch.manual_seed(seed)
    # Anchors on a surface, voxelized as HAC:GaussianModel.voxelize_sample does.
    u = rng.uniform(0, 2 * np.pi, 6 * n_target)
    w = rng.uniform(0, 2 * np.pi, 6 * n_target)
    pts = np.stack([(1 + 0.4 * np.cos(w)) * np.cos(u) + 0.3, (1 + 0.4 * np.cos(w)) * np.sin(u) - 0.2,
                    0.4 * np.sin(w) + 0.5], 1)
    pts = np.unique(np.round(pts / vs), axis=0) * vs
    pts = pts[rng.permutation(len(pts))[:n_target]]
    anchor = torch.tensor(pts).float()
    n = anchor.shape[0]
    feat = torch.from_numpy((rng.normal(size=(n, 4)) @ rng.normal(size=(4, f)) * 2
                             + rng.normal(size=(n, f)) * 0.5).astype(np.float32))
    offset = torch.from_numpy(rng.normal(size=(n, k, 3)).astype(np.float32) * 0.6)
    mask_logit = torch.from_numpy(rng.normal(loc=-2.0, scale=4.0, size=(n, k, 1)).astype(np.float32))
    mask_logit[: max(3, n // 50)] = -10.0            # some anchors spawn nothing
    scaling_log = torch.log(torch.from_numpy((vs * rng.uniform(1, 16, size=(n, 6))).astype(np.float32)))
    rotation = torch.zeros(n, 4)
    rotation[:, 0] = 1
    opacity = torch.logit(torch.full((n, 1), 0.1))

    lo, hi = hac_bound(anchor)
    lo_np, hi_np = lo.numpy()[0].astype(np.float64), hi.numpy()[0].astype(np.float64)
    enc = Mix3D2D(c, res3, t3, res2, t2) if use_2d else GridEncoderLike(3, c, res3, t3)
    raw_params = not decoded
    if use_2d:
        fill_smooth_grid(enc.encoding_xyz, [0, 1, 2], lo_np, hi_np, rng, raw_params)
        fill_smooth_grid(enc.encoding_xy, [0, 1], lo_np, hi_np, rng, raw_params)
        fill_smooth_grid(enc.encoding_xz, [0, 2], lo_np, hi_np, rng, raw_params)
        fill_smooth_grid(enc.encoding_yz, [1, 2], lo_np, hi_np, rng, raw_params)
        cin = c * (len(res3) + 3 * len(res2))
    else:
        fill_smooth_grid(enc, [0, 1, 2], lo_np, hi_np, rng, raw_params)
        cin = c * len(res3)

    # HAC:scene/gaussian_model.py:GaussianModel.__init__ MLPs.
    mlp_opacity = nn.Sequential(nn.Linear(f + 3 + 1, f), nn.ReLU(True), nn.Linear(f, k), nn.Tanh())
    mlp_cov = nn.Sequential(nn.Linear(f + 3 + 1, f), nn.ReLU(True), nn.Linear(f, 7 * k))
    mlp_color = nn.Sequential(nn.Linear(f + 3 + 1, f), nn.ReLU(True), nn.Linear(f, 3 * k), nn.Sigmoid())
    mlp_grid = nn.Sequential(nn.Linear(cin, f * 2), nn.ReLU(True), nn.Linear(f * 2, (f + 6 + 3 * k) * 2 + 1 + 1 + 1))
    mlp_deform = nn.Sequential(nn.Linear(cin, f * 2), nn.ReLU(True), nn.Linear(f * 2, 2 * k))
    with torch.no_grad():   # a plausible trained prior: positive scales of the right size
        w2, b2 = mlp_grid[2].weight, mlp_grid[2].bias
        w2.mul_(0.05)
        b2.zero_()
        b2[f:2 * f] = 2.0
        b2[2 * f:2 * f + 6] = float(torch.exp(scaling_log).mean())
        b2[2 * f + 6:2 * f + 12] = 0.02
        b2[2 * f + 12 + 3 * k:2 * f + 12 + 6 * k] = 0.5
        w2[2 * f + 6:2 * f + 12] *= 0.01
    ck = {"opacity_mlp": mlp_opacity.state_dict(), "cov_mlp": mlp_cov.state_dict(),
          "color_mlp": mlp_color.state_dict(), "encoding_xyz": enc.state_dict(),
          "grid_mlp": mlp_grid.state_dict(), "deform_mlp": mlp_deform.state_dict()}
    if feature_bank:
        ck["mlp_feature_bank"] = nn.Sequential(nn.Linear(4, f), nn.ReLU(True), nn.Linear(f, 3)).state_dict()
    truth = {"n_ply": n}
    if salvq:
        # SALVQ:scene/gaussian_model.py: P.orthogonal(nn.Linear(F, F, bias=False)) twice and a
        # Gain [1, F]; "trained": random skew generators and gains in 0.5 .. 2.
        mlp_u = P.orthogonal(nn.Linear(f, f, bias=False))
        mlp_v = P.orthogonal(nn.Linear(f, f, bias=False))
        with torch.no_grad():
            mlp_u.parametrizations.weight.original.copy_(torch.randn(f, f) * 0.3)
            mlp_v.parametrizations.weight.original.copy_(torch.randn(f, f) * 0.3)
            gain = torch.from_numpy(rng.uniform(0.5, 2.0, size=(1, f)).astype(np.float32))
            truth["W_U"] = mlp_u.weight.numpy().copy()
            truth["W_V"] = mlp_v.weight.numpy().copy()
        truth["gain"] = gain.numpy()[0]
        ck["mlp_U"] = mlp_u.state_dict()
        ck["mlp_V"] = mlp_v.state_dict()
        ck["gain"] = gain.detach().cpu()

    mask_bin = (torch.sigmoid(mask_logit) > 0.01).float()          # get_mask
    if decoded:
        # What scene.save writes after training_report ran conduct_encoding/decoding
        # (run_codec = True): anchors whose masks are not all zero first, their positions
        # HAC's 16-bit floor-quantized ones, values decoded (quantized), masks 0/1, scaling
        # activated; the remaining rows zero-filled.
        keep = mask_bin.sum(dim=(1, 2)) > 0
        nk = int(keep.sum())
        a_dec, interval = hac_quantize(anchor[keep], lo, hi)
        z = lambda shape: torch.zeros(shape)  # noqa: E731
        P_anchor = torch.cat([a_dec, z((n - nk, 3))])
        P_feat = torch.cat([torch.round(feat[keep]), z((n - nk, f))])
        sc = torch.round(torch.exp(scaling_log[keep]) / 0.001) * 0.001
        P_scale = torch.cat([sc, z((n - nk, 6))])
        mk = mask_bin[keep]
        P_offset = torch.cat([torch.round(offset[keep] / 0.2) * 0.2 * mk, z((n - nk, k, 3))])
        P_mask = torch.cat([mk, z((n - nk, k, 1))])
        truth.update(anchor=anchor[keep].numpy(), pos_ply=a_dec.numpy(),
                     interval=interval.numpy()[0], feat=P_feat[:nk].numpy(),
                     scaling=sc.numpy(), offsets=P_offset[:nk].numpy(), mask=mk[..., 0].numpy())
        P_rot, P_opa = rotation, opacity
    else:
        P_anchor, P_feat, P_scale, P_offset, P_mask = anchor, feat, scaling_log, offset, mask_logit
        P_rot, P_opa = rotation, opacity
        truth.update(anchor=anchor.numpy(), pos_ply=anchor.numpy(), feat=feat.numpy(),
                     scaling=torch.exp(scaling_log).numpy(), offsets=offset.numpy(),
                     mask=mask_bin[..., 0].numpy())
    # HAC:scene/gaussian_model.py:save_ply / construct_list_of_attributes.
    names = ["x", "y", "z", "nx", "ny", "nz"]
    names += [f"f_offset_{i}" for i in range(3 * k)] + [f"f_mask_{i}" for i in range(k)]
    names += [f"f_anchor_feat_{i}" for i in range(f)] + ["opacity"]
    names += [f"scale_{i}" for i in range(6)] + [f"rot_{i}" for i in range(4)]
    data = np.concatenate([P_anchor.numpy(), np.zeros((n, 3), np.float32),
                           P_offset.transpose(1, 2).flatten(start_dim=1).numpy(),
                           P_mask.transpose(1, 2).flatten(start_dim=1).numpy(),
                           P_feat.numpy(), P_opa.numpy(), P_scale.numpy(), P_rot.numpy()], axis=1)
    it = root / "point_cloud" / f"iteration_{iteration}"
    write_ply(it / "point_cloud.ply", names, data)
    torch.save(ck, it / "checkpoint.pth")
    (root / "cfg_args").write_text(
        f"Namespace(feat_dim={f}, n_offsets={k}, voxel_size={vs if cfg_vs is None else cfg_vs}, update_init_factor=16, "
        f"use_feat_bank={feature_bank}, log2={t3}, log2_2D={t2}, n_features={c}, lmbda=0.004, "
        f"model_path='{root}', source_path='/data/scene', eval=True)")
    truth.update(ck=ck, lo=lo.numpy()[0], hi=hi.numpy()[0], vs=vs, f=f, k=k)
    return truth
