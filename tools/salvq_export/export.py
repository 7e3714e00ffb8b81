"""The export itself (A.7): the run's files -> the Annex A tensors and a report. Each step is
in the module of its concern; this one calls them in order and fills the report."""
from __future__ import annotations

import numpy as np

from .checkpoint import checkpoint_format, load_checkpoint, read_mlps, salvq_basis
from .common import HAC_Q_FEAT, HAC_Q_OFFSETS, HAC_Q_SCALING
from .estimate import estimate_bits
from .grid import grid_contexts, map_grids, read_hac_grids
from .model import validate
from .ply import read_anchors
from .run_folder import locate, read_cfg_args
from .voxels import normalization_box, voxel_grid


def export(args) -> dict:
    """args: the command line (cli.py). Returns the report (what summary() prints, and the
    --json file) with the tensors under "tensors" and the feature lattice under "lattice"."""
    import torch
    torch.set_grad_enabled(False)
    ply, ckpt_path, cfg_path = locate(args.run_dir, args.iteration, args.ply, args.checkpoint)
    cfg = read_cfg_args(cfg_path)
    ck = load_checkpoint(ckpt_path)
    rep = {"ply": str(ply), "checkpoint": str(ckpt_path), "cfg_args": str(cfg_path) if cfg_path else None,
           "notes": []}
    note = rep["notes"].append

    # -- format (A.7.1).
    fmt = checkpoint_format(ck, ckpt_path, cfg, args.format, note)
    rep["format"] = fmt

    # -- PLY and its state (A.7.2).
    a = read_anchors(ply, args.state, args.drop_empty_anchors, note)
    state, n_all, f, k, s_dim = a.state, a.n_all, a.f, a.k, a.s_dim
    pos, feat, offsets, mask, scaling = a.pos, a.feat, a.offsets, a.mask, a.scaling
    rep["state"] = state
    n = int(pos.shape[0])
    rep["anchors"] = {"in_ply": n_all, "exported": n, "with_empty_mask": int((mask.sum(1) == 0).sum())}

    # -- voxel grid (A.7.3).
    kk, vs, vox, vs32, origin, bits, rep["voxels"] = voxel_grid(pos, state, args.voxel_size, cfg,
                                                                args.snap, note)

    # -- HAC's normalization box (A.7.4): not saved; recomputed from the exported anchors.
    world, lo, hi, rep["x_bound"] = normalization_box(kk, vs, pos, state, args.x_bound_min,
                                                      args.x_bound_max)

    # -- hash grids (A.7.4).
    levels, use_2d, c, t3, t2 = read_hac_grids(ck["encoding_xyz"], cfg)
    grids, res_ours, grid_info = map_grids(levels, vox, bits, origin.astype(np.float64),
                                           float(vs32), lo.astype(np.float64),
                                           hi.astype(np.float64), args.grid_resolutions, t3, t2)
    l3 = len(res_ours["3d"])
    l2 = len(res_ours.get("xy", []))
    cin = c * (l3 + 3 * l2)

    # -- MLPs (A.7.5).
    t, h, hs, vdim, cout = read_mlps(ck, f, k, s_dim, cin, note)

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


