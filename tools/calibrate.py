#!/usr/bin/env python3
"""Measure statistics of REAL scene data so salvq's synthetic scene generator is realistic.

Usage (from the repository root):  python3 tools/calibrate.py /work/shared/data
Prints JSON and also writes it to tools/calibration.json (next to this script).
Needs numpy and scipy (pip install numpy scipy). Fully deterministic: no sampling.

A. anchors (octree_gs_partial, one Octree-GS run; level l uses voxel base/2^l):
   - count, voxel, grid origin / on-grid fractions: do anchors sit exactly on a voxel lattice
     (the codec's position coder assumes integer voxel coordinates)?
   - distinct voxels and anchors-per-occupied-voxel histogram: how often coordinates repeat.
   - bbox extent in voxels: how many bits a coordinate needs.
   - nearest-neighbour (NN) distance in voxel units: how dense/contiguous the lattice is.
   - surface-ness: PCA of each occupied voxel + its 16 nearest neighbours; l3/(l1+l2+l3) ~ 0
     means the anchors lie on a surface, l2/l1 ~ 0 means a curve/line.
   - octree occupancy: mean occupied children per occupied node, root -> leaves; this is
     what an octree/occupancy coder sees and what a generator must reproduce.
   - log(exp-scale / voxel): anchor scaling (scale_3..5) relative to the voxel size.
B. MLP weights (opacity/cov/color, Linear(35->32), ReLU, Linear(32->out)): per layer
   mean/std/min/max and std*sqrt(fan_in) (PyTorch default init gives 1/sqrt(3) = 0.577);
   first-layer std of the 32 feature columns vs the 3 view-direction columns.
C. 3DGS PLYs: log-scale and opacity-logit quantiles, fraction with sigmoid(opacity) < 0.01
   (what a pruning mask would drop), NN spacing and median(exp(scale))/median(NN).
"""
import json
import sys
import zipfile
from pathlib import Path

import numpy as np
import scipy
from scipy.spatial import cKDTree

Q = [10, 25, 50, 75, 90]


def r(x):
    """Round to 6 significant digits so the JSON is readable and stable."""
    return float(f"{float(x):.6g}")


def quant(a, qs=(10, 50, 90)):
    a = np.asarray(a, dtype=np.float64).ravel()
    return {f"p{q}" if q != 50 else "median": r(v) for q, v in zip(qs, np.percentile(a, qs))}


# ---------------------------------------------------------------- A. anchors
def nn_stats(pts_vox):
    """NN distance (voxel units) of each point to any other point, and its histogram."""
    d = cKDTree(pts_vox).query(pts_vox, k=2)[0][:, 1]
    edges = [("0_duplicate", -1, 0.5), ("1", 0.5, 1.2), ("sqrt2", 1.2, 1.6), ("sqrt3", 1.6, 1.9),
             ("2", 1.9, 2.1), ("2.1_to_4", 2.1, 4.0), ("over_4", 4.0, np.inf)]
    hist = {name: r(np.mean((d > lo) & (d <= hi))) for name, lo, hi in edges}
    return {**quant(d), "mean": r(d.mean()), "histogram_fraction": hist}


def surfaceness(pts_vox, k=16):
    """Local PCA over each point and its k nearest neighbours (k+1 points)."""
    idx = cKDTree(pts_vox).query(pts_vox, k=k + 1)[1]
    nb = pts_vox[idx]                                      # (N, k+1, 3)
    nb = nb - nb.mean(axis=1, keepdims=True)
    cov = np.einsum("nki,nkj->nij", nb, nb) / (k + 1)
    ev = np.linalg.eigvalsh(cov)[:, ::-1]                  # l1 >= l2 >= l3
    tot = ev.sum(1)
    l3_frac = ev[:, 2] / tot
    l2_l1 = ev[:, 1] / ev[:, 0]
    return {"neighbours": k, "points": int(len(pts_vox)),
            "l3_over_sum": {**quant(l3_frac, Q), "frac_below_0.01": r(np.mean(l3_frac < 0.01)),
                            "frac_below_0.05": r(np.mean(l3_frac < 0.05))},
            "l2_over_l1": quant(l2_l1, Q)}


def octree_occupancy(keys):
    """keys: distinct non-negative int voxel coords. Children per occupied node by depth."""
    depth = max(1, int(np.ceil(np.log2(keys.max() + 1))))
    counts, child_mean, child_hist = [], [], []
    prev = None
    for d in range(depth + 1):                             # d = 0 root ... depth = leaves
        k = keys >> (depth - d)
        code = (k[:, 0] << 42) | (k[:, 1] << 21) | k[:, 2]
        u = np.unique(code)
        counts.append(int(len(u)))
        if prev is not None:
            # parent of each node at depth d = code at depth d-1; count children per parent
            kk = np.stack([(u >> 42) & 0x1FFFFF, (u >> 21) & 0x1FFFFF, u & 0x1FFFFF], 1) >> 1
            pc = (kk[:, 0] << 42) | (kk[:, 1] << 21) | kk[:, 2]
            n_children = np.unique(pc, return_counts=True)[1]
            child_mean.append(r(n_children.mean()))
            child_hist.append([r(v) for v in np.bincount(n_children, minlength=9)[1:] / len(n_children)])
        prev = u
    return {"depth": depth, "occupied_nodes_per_depth": counts,
            "mean_children_per_node_by_depth": child_mean,
            "children_count_fraction_1_to_8_by_depth": child_hist}


def grid_block(pos, scales, voxel, origin, scale_voxel=None):
    """All lattice statistics for one set of anchors on a grid of spacing `voxel`.
    Scales are divided by `scale_voxel` (each anchor's own level voxel) if given, else by `voxel`."""
    f0 = pos / voxel
    res0 = np.abs(f0 - np.round(f0))
    f = (pos - origin) / voxel
    res = np.abs(f - np.round(f))
    keys = np.round(f).astype(np.int64)
    uniq, per_voxel = np.unique(keys, axis=0, return_counts=True)
    dup = np.bincount(np.minimum(per_voxel, 4), minlength=5)[1:]
    ext = keys.max(0) - keys.min(0) + 1
    sv = voxel if scale_voxel is None else np.asarray(scale_voxel, dtype=np.float64)[:, None]
    ls = np.log(scales.astype(np.float64) / sv)
    return {
        "count": int(len(pos)), "voxel_size": r(voxel),
        "on_grid_fraction_origin_zero": r(np.mean(np.all(res0 < 1e-3, 1))),
        "on_grid_fraction_origin_min": r(np.mean(np.all(res < 1e-3, 1))),
        "max_snap_residual_voxels": r(res.max()),
        "grid_origin_fractional_offset_voxels": [r(v) for v in np.median(f0 - np.floor(f0), 0)],
        "distinct_voxels": int(len(uniq)),
        "occupied_voxels_by_anchor_count_1_2_3_4plus": [int(v) for v in dup],
        "anchors_per_occupied_voxel_max": int(per_voxel.max()),
        "anchors_in_shared_voxels_fraction": r(per_voxel[per_voxel > 1].sum() / len(pos)),
        "bbox_extent_voxels": [int(v) for v in ext],
        "nn_distance_voxels_all_anchors": nn_stats(keys.astype(np.float64)),
        "nn_distance_voxels_distinct_voxels": nn_stats(uniq.astype(np.float64)),
        "surfaceness_distinct_voxels": surfaceness(uniq.astype(np.float64)),
        "octree_over_distinct_voxels": octree_occupancy(uniq - uniq.min(0)),
        "log_exp_scale_over_voxel": {"per_axis": [quant(ls[:, a]) for a in range(3)],
                                     "overall": quant(ls),
                                     "per_anchor_max_axis": quant(ls.max(1))},
    }


def anchors(root):
    d = root / "octree_gs_partial"
    pos = np.fromfile(d / "anchor_positions.bin", "<f4").reshape(-1, 3).astype(np.float64)
    lev = np.fromfile(d / "anchor_levels.bin", "<f4")
    sc = np.fromfile(d / "anchor_scales.bin", "<f4").reshape(-1, 3)
    extra = np.fromfile(d / "anchor_extra_levels.bin", "<f4")
    info = np.fromfile(d / "anchor_info.bin", "<f4")
    base = float(info[0])
    origin = pos[lev == 0].min(0)          # level-0 minimum; shared lattice origin of all levels
    out = {"info": [r(v) for v in info], "base_voxel_size": r(base),
           "extra_level": {**quant(extra), "frac_zero": r(np.mean(extra == 0))}, "levels": {}}
    for lv in sorted(np.unique(lev).astype(int)):
        m = lev == lv
        out["levels"][str(lv)] = grid_block(pos[m], sc[m], base / 2 ** lv, origin)
    fine = base / 2 ** int(lev.max())
    out["overall_on_finest_grid"] = grid_block(pos, sc, fine, origin, scale_voxel=base / 2.0 ** lev)
    # cross-level: how many level-1 voxels coincide with a level-0 anchor position
    k = np.round((pos - origin) / fine).astype(np.int64)
    k0 = {tuple(v) for v in np.unique(k[lev == 0], axis=0)}
    k1 = np.unique(k[lev == 1], axis=0)
    out["level1_voxels_coinciding_with_level0_anchor"] = int(sum(tuple(v) in k0 for v in k1))
    return out


# ---------------------------------------------------------------- B. MLPs
def mlps(root):
    out = {}
    for name in ("opacity", "cov", "color"):
        z = zipfile.ZipFile(root / "octree_gs_partial" / f"{name}_mlp.pt")
        t = {m.split("/")[-1]: np.frombuffer(z.read(m), "<f4").astype(np.float64)
             for m in z.namelist() if m.split("/")[-2:-1] == ["data"]}
        w0, b0, w1, b1 = t["0"], t["1"], t["2"], t["3"]
        hid = b0.size
        w0 = w0.reshape(hid, -1)
        w1 = w1.reshape(b1.size, hid)
        layers = []
        for w, b in ((w0, b0), (w1, b1)):
            layers.append({"shape_out_in": list(w.shape),
                           "weight": {"mean": r(w.mean()), "std": r(w.std()), "min": r(w.min()),
                                      "max": r(w.max()), "std_x_sqrt_fan_in": r(w.std() * np.sqrt(w.shape[1]))},
                           "bias": {"mean": r(b.mean()), "std": r(b.std()), "min": r(b.min()), "max": r(b.max())}})
        layers[0]["feature_cols_0_31_std"] = r(w0[:, :32].std())
        layers[0]["viewdir_cols_32_34_std"] = r(w0[:, 32:].std())
        layers[0]["feature_col_l2norm_median"] = r(np.median(np.linalg.norm(w0[:, :32], axis=0)))
        layers[0]["viewdir_col_l2norm"] = [r(v) for v in np.linalg.norm(w0[:, 32:], axis=0)]
        out[name] = layers
    return out


# ---------------------------------------------------------------- C. 3DGS scenes
def read_ply(path):
    data = path.read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode("ascii").splitlines()
    assert "format binary_little_endian 1.0" in header, path
    n = next(int(l.split()[2]) for l in header if l.startswith("element vertex"))
    props = [l.split()[2] for l in header if l.startswith("property float")]
    assert len(props) == sum(l.startswith("property") for l in header), "non-float property"
    arr = np.frombuffer(data, "<f4", count=n * len(props), offset=end).reshape(n, len(props))
    return {p: arr[:, i].astype(np.float64) for i, p in enumerate(props)}


def scenes(root):
    out = {}
    thr = np.log(0.01 / 0.99)                     # sigmoid(x) < 0.01  <=>  x < logit(0.01)
    for name in ("fruit_drops", "donut", "guitar", "playbot"):
        v = read_ply(root / f"{name}.ply")
        xyz = np.stack([v["x"], v["y"], v["z"]], 1)
        ls = np.stack([v[f"scale_{i}"] for i in range(3)], 1)
        op = v["opacity"]
        nn = cKDTree(xyz).query(xyz, k=2)[0][:, 1]
        nn_med = np.median(nn)
        out[name] = {
            "count": int(len(op)),
            "log_scale_all_axes": quant(ls), "log_scale_per_gaussian_max": quant(ls.max(1)),
            "log_scale_per_gaussian_min": quant(ls.min(1)),
            "opacity_logit": quant(op), "frac_sigmoid_opacity_below_0.01": r(np.mean(op < thr)),
            "frac_sigmoid_opacity_below_0.05": r(np.mean(op < np.log(0.05 / 0.95))),
            "nn_distance": {**quant(nn), "frac_zero": r(np.mean(nn == 0))},
            "ratio_median_exp_scale_over_median_nn": r(np.median(np.exp(ls)) / nn_med),
            "ratio_median_exp_max_scale_over_median_nn": r(np.median(np.exp(ls.max(1))) / nn_med),
        }
    return out


DESCRIPTION = {
    "anchors": "Octree-GS anchors; levels[l] on voxel base/2^l; grid coords = round((p - origin)/voxel), "
               "origin = min of level-0 positions (shared lattice for all levels). "
               "nn_* in voxel units (all_anchors includes duplicates -> 0); surfaceness/octree use distinct voxels. "
               "surfaceness: PCA of voxel + 16 NN, l3/(l1+l2+l3) near 0 = surface, l2/l1 near 0 = line. "
               "octree: depth 0 = root; mean_children[d] = occupied nodes at depth d+1 / at depth d. "
               "log_exp_scale_over_voxel = ln(exp(scale_3..5) / voxel of the anchor's own level).",
    "mlps": "Raw float32 tensors data/0..3 = W0 [32x35], b0, W1 [out x 32], b1 (PyTorch out x in). "
            "std_x_sqrt_fan_in: PyTorch default Linear init gives 0.577; input cols 0..31 = anchor feature, 32..34 = view dir.",
    "scenes": "3DGS PLYs (Inria layout): log_scale = scale_*; opacity_logit = opacity; nn_distance in scene units; "
              "ratio = median(exp(scale_*) pooled over axes) / median NN distance. guitar/playbot passed through lossy "
              "web formats (8-bit opacity; guitar alpha 0/1 -> logit -/+40).",
}


def main():
    root = Path(sys.argv[1] if len(sys.argv) > 1 else "/work/shared/data")
    res = {"description": DESCRIPTION, "numpy": np.__version__, "scipy": scipy.__version__,
           "anchors": anchors(root), "mlps": mlps(root), "scenes": scenes(root)}
    text = json.dumps(res, indent=1)
    print(text)
    (Path(__file__).resolve().parent / "calibration.json").write_text(text + "\n")


if __name__ == "__main__":
    main()
