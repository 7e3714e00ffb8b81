"""The checks of one decoded model against the checkpoint it was exported from: lossless
tensors, `mlp_grid` within half the stream's unit, the quantized attributes within each
anchor's own half step or the lattice's Babai bound, positions, the SALVQ basis, and the
resampled grid against HAC's own lookup."""
from __future__ import annotations

import numpy as np
import torch

from .hac_grid import hac_features_torch
from .harness import check, table_row
from .stream import parse_mlps, spec_features, spec_steps
from .training_output import hac_quantize


def morton(v):
    code = np.zeros(len(v), np.uint64)
    for i in range(21):
        for a in range(3):
            code |= ((v[:, a].astype(np.uint64) >> np.uint64(i)) & np.uint64(1)) << np.uint64(3 * i + a)
    return code


def compare(tag, truth, exp, dec, info, stream, *, salvq, rigorous_lattice, decoded_state, use_2d,
            rep, grid_check):
    ck = truth["ck"]
    n = exp["anchor.feat"].shape[0]
    print(f"  -- {tag}: {n} anchors")
    perm = np.argsort(morton(exp["anchor.voxel"]), kind="stable")      # §2.2 canonical order
    ok_all = True

    def row(name, err, bound, ok):
        nonlocal ok_all
        table_row(name, err, bound, ok)
        ok_all &= bool(ok)

    # Lossless tensors: exported == decoded.
    for nm in ("geometry.origin", "geometry.voxel_size", "hyperprior.resolutions_3d",
               "hyperprior.resolutions_2d", "hyperprior.log2_size",
               "quant.feat.gains", "quant.scaling.gains", "quant.offsets.gains") + (
            ("quant.feat.basis_u", "quant.feat.basis_s", "quant.feat.basis_v") if salvq else ()):
        same = np.array_equal(exp[nm], dec[nm])
        row(nm, 0.0 if same else float(np.abs(exp[nm].astype(float) - dec[nm].astype(float)).max()), "lossless", same)
    # Base steps: lossless, but for the refinement the encoder may apply with i8 context-MLP
    # weights to hold the distortion (Annex A.5.4): a factor in [1/sqrt(1.05), 1].
    for nm in ("quant.feat.step", "quant.scaling.step", "quant.offsets.step"):
        e, d = float(exp[nm][0]), float(dec[nm][0])
        ratio = d / e
        row(nm, abs(d - e), "x[0.976, 1] (A.5.4)", 1.0 / 1.05 ** 0.5 - 1e-7 <= ratio <= 1.0)
    vox = dec["anchor.voxel"].astype(np.int64)
    row("anchor.voxel", float(np.abs(exp["anchor.voxel"][perm] - vox).max()), "lossless",
        np.array_equal(exp["anchor.voxel"][perm], vox))
    # Our anchors vs the checkpoint's: the exporter keeps the checkpoint's order before sorting.
    tmask = truth["mask"].astype(np.uint8)
    keep = np.ones(len(tmask), bool)
    if len(tmask) != n:   # --drop-empty-anchors
        keep = tmask.sum(1) > 0
    assert keep.sum() == n, (keep.sum(), n)
    t_feat, t_scal, t_off, t_anchor = (truth[x][keep] for x in ("feat", "scaling", "offsets", "anchor"))
    t_mask, t_pos = tmask[keep][perm], truth["pos_ply"][keep][perm]
    row("anchor.mask", float(np.abs(dec["anchor.mask"].astype(int) - t_mask).max()), "lossless",
        np.array_equal(dec["anchor.mask"], t_mask))
    vs = float(dec["geometry.voxel_size"][0])
    world = dec["geometry.origin"][None].astype(np.float64) + vs * vox
    if decoded_state:
        # HAC stored floor-quantized positions: a_dec <= voxel position < a_dec + interval.
        lo_ok = world >= t_pos - 1e-6
        hi_ok = world < t_pos + truth["interval"][None] + 1e-6
        err = float(np.abs(world - t_anchor[perm]).max())
        row("positions (voxel grid)", err, "in [a_dec, a_dec+interval)", lo_ok.all() and hi_ok.all())
    else:
        err = float(np.abs(world - t_pos).max())
        row("positions (voxel grid)", err, 1e-3 * vs, err <= 1e-3 * vs)

    # MLPS chunk: units of the integer context MLP, and the Scaffold-GS precision.
    cin = dec["mlp_grid.0.weight"].shape[1]
    h = dec["mlp_grid.0.weight"].shape[0]
    cout = dec["mlp_grid.2.weight"].shape[0]
    m = parse_mlps(stream, info, cin, h, cout)
    a0, qh = m["a0"], 8 + m["a0"] - m["shift0"]
    units = {"mlp_grid.0.weight": np.full((h, 1), 2.0 ** -a0), "mlp_grid.0.bias": np.full(h, 2.0 ** -(8 + a0)),
             "mlp_grid.2.weight": (2.0 ** -m["a1"].astype(float))[:, None],
             "mlp_grid.2.bias": 2.0 ** -(qh + m["a1"]).astype(float)}
    ints = {"mlp_grid.0.weight": m["w0"], "mlp_grid.0.bias": m["b0"], "mlp_grid.2.weight": m["w1"],
            "mlp_grid.2.bias": m["b1"]}
    src = {"mlp_grid": "grid_mlp", "mlp_opacity": "opacity_mlp", "mlp_cov": "cov_mlp", "mlp_color": "color_mlp"}
    for nm, unit in units.items():
        orig = ck["grid_mlp"][nm.split(".", 1)[1]].numpy().astype(np.float64)
        d = dec[nm].astype(np.float64)
        exact = np.array_equal(dec[nm], (ints[nm] * unit).astype(np.float32))
        err = np.abs(d - orig)
        bound = unit / 2 * (1 + 1e-6) + np.abs(orig) * 2.0 ** -23
        row(nm, float(err.max()), f"unit/2 ({'%.3g' % float(np.max(unit))}..)", exact and (err <= bound).all())
    prec = m["precision"]
    for mlp in ("mlp_opacity", "mlp_cov", "mlp_color"):
        for p in ("0.weight", "0.bias", "2.weight", "2.bias"):
            nm = f"{mlp}.{p}"
            orig = ck[src[mlp]][p].numpy()
            want = orig if prec == 0 else orig.astype(np.float16).astype(np.float32)
            same = np.array_equal(exp[nm], orig) and np.array_equal(dec[nm], want)
            row(nm, float(np.abs(dec[nm] - orig).max()), "lossless" if prec == 0 else "f16 rounding", same)

    # Hash grid: touched entries as exported, the others +1; exported vs checkpoint below.
    bits = info["head"]["coord_bits"]
    _, touched = spec_features(dec, vox, bits)
    for pl in ("grid_3d", "grid_xy", "grid_xz", "grid_yz"):
        nm = "hyperprior." + pl
        t_idx = np.array(sorted(touched.get(pl, ())), np.int64)
        untouched = np.ones(len(dec[nm]), bool)
        untouched[t_idx] = False
        ok = np.array_equal(dec[nm][t_idx], exp[nm][t_idx]) and (dec[nm][untouched] == 1).all() \
            and np.isin(exp[nm], (-1, 1)).all()
        row(nm, 0.0 if ok else 2.0, f"lossless ({len(t_idx)} touched)", ok)

    # Quantized attributes, with each anchor's own step (§5.4) and the lattice (§7).
    rate = info["head"]["coded_rates"][0]          # the decoder's default: the lowest coded rate
    steps = spec_steps(dec, vox, bits, m, cout, rate)
    slack = lambda x, y: 2.0 ** -20 * (np.abs(x) + np.abs(y)) + 1e-12  # noqa: E731
    fe = dec["anchor.feat"].astype(np.float64)
    tf = t_feat[perm].astype(np.float64)
    lattice = info["head"]["feat_lattice"]      # `--quantizer model`: the model's own
    want = "basis" if salvq else "identity"
    row("feature lattice", 0.0 if lattice == want else 1.0, want, lattice == want)
    if lattice == "basis":
        U, s, V = (dec[f"quant.feat.basis_{x}"].astype(np.float64) for x in "usv")
        B = (U * s[None]) @ V.T
        if rigorous_lattice:
            bound = steps["feat"][:, None] / 2 * np.abs(B).sum(1)[None]
            err = np.abs(fe - tf)
            row("anchor.feat (Babai rounding)", float(err.max()), "Delta/2 sum_j|B_ij|",
                (err <= bound * (1 + 1e-6) + slack(fe, tf)).all())
            print(f"      worst error / bound {float((err / bound).max()):.3f}")
        else:
            # Nearest plane on the reduced basis has no per-coordinate bound in terms of B;
            # it is checked against rounding's Euclidean bound (a sanity check only).
            en = np.linalg.norm(fe - tf, axis=1)
            bound = steps["feat"] / 2 * np.linalg.norm(B, axis=0).sum()
            row("anchor.feat (auto search)", float(en.max()), "Delta/2 sum_j||b_j|| (L2)", (en <= bound).all())
            print(f"      feature MSE {float(((fe - tf) ** 2).mean()):.4g}; worst L2 error / bound "
                  f"{float((en / bound).max()):.3f}")
    else:
        err = np.abs(fe - tf)
        bound = steps["feat"][:, None] / 2
        row("anchor.feat (identity)", float(err.max()), f"Delta/2 (<= {float(bound.max()):.3g})",
            (err <= bound * (1 + 1e-6) + slack(fe, tf)).all())
    sc, ts = dec["anchor.scaling"].astype(np.float64), t_scal[perm].astype(np.float64)
    bound = steps["scaling"][:, None] / 2
    err = np.abs(sc - ts)
    row("anchor.scaling (identity)", float(err.max()), f"Delta/2 (<= {float(bound.max()):.3g})",
        (err <= bound * (1 + 1e-6) + slack(sc, ts)).all())
    of, to = dec["anchor.offsets"].astype(np.float64), t_off[perm].astype(np.float64)
    mk = t_mask.astype(bool)
    err = np.abs(of - to)[mk]
    bound = np.broadcast_to(steps["offsets"][:, None, None] / 2, of.shape)[mk]
    row("anchor.offsets (identity)", float(err.max(initial=0)), f"Delta/2 (<= {float(bound.max(initial=0)):.3g})",
        (err <= bound * (1 + 1e-6) + slack(of[mk], to[mk])).all())
    row("anchor.offsets (masked)", float(np.abs(of[~mk]).max(initial=0)), "0.0 exactly", (of[~mk] == 0).all())

    # Lattice factors vs the checkpoint's orthogonal parametrizations and gain (A.7.6).
    if salvq:
        wu, wv, g = truth["W_U"], truth["W_V"], truth["gain"]
        same = np.array_equal(exp["quant.feat.basis_u"], np.ascontiguousarray(wv.T)) and \
            np.array_equal(exp["quant.feat.basis_v"], wu) and \
            np.array_equal(exp["quant.feat.basis_s"], (1 / g.astype(np.float64)).astype(np.float32))
        row("basis = W_V^T, 1/gain, W_U", 0.0 if same else 1.0, "exact", same)
        Bs = wv.T.astype(np.float64) @ np.diag(1 / g.astype(np.float64)) @ wu.T.astype(np.float64)
        e = float(np.abs(B - Bs).max())
        row("B vs SALVQ's decoder matrix", e, 1e-5, e <= 1e-5)

    # Grid resampling (approximation): HAC's features at HAC's anchors vs ours at ours.
    if grid_check:
        lo, hi = np.array(rep["x_bound"]["min"], np.float32), np.array(rep["x_bound"]["max"], np.float32)
        a_q, _ = hac_quantize(torch.from_numpy(world.astype(np.float32)), torch.from_numpy(lo)[None],
                              torch.from_numpy(hi)[None])
        p_norm = ((a_q - torch.from_numpy(lo)[None]) / torch.from_numpy(hi - lo)[None]).numpy()
        hac = hac_features_torch(ck["encoding_xyz"], use_2d, p_norm)
        ours = spec_features(dec, vox, bits)[0] / 256.0
        diff = np.abs(hac - ours)
        # The test's trained grid is smooth on HAC's dense levels (noise on hashed ones).
        c = dec["hyperprior.grid_3d"].shape[1]
        dense, cols, col = [], [], 0
        for prefix, d in ((("encoding_xyz.", 3), ("encoding_xy.", 2), ("encoding_xz.", 2),
                           ("encoding_yz.", 2)) if use_2d else (("", 3),)):
            offs = ck["encoding_xyz"][prefix + "offsets_list"].tolist()
            for li, r in enumerate(ck["encoding_xyz"][prefix + "resolutions_list"].tolist()):
                if r ** d <= offs[li + 1] - offs[li]:
                    dense.append(f"{prefix[9:-1] or 'xyz'}{li}")
                    cols.extend(range(col, col + c))
                col += c
        dcols = np.array(cols)
        md = float(diff[:, dcols].mean())
        agree = float((np.sign(hac[:, dcols]) == np.sign(ours[:, dcols])).mean())
        print(f"      grid: mean |HAC - ours| {float(diff.mean()):.3f} over all levels, {md:.3f} on HAC's "
              f"dense levels {dense} (same sign {100 * agree:.1f} %); exporter measured "
              f"{rep['grid']['mean_abs_feature_difference']:.3f}")
        row("grid features (dense levels)", md, 0.08, md <= 0.08)
        row("exporter's grid measure", abs(float(diff.mean()) - rep["grid"]["mean_abs_feature_difference"]),
            1e-4, abs(float(diff.mean()) - rep["grid"]["mean_abs_feature_difference"]) <= 1e-4)
    check(f"{tag}: every tensor", ok_all)
