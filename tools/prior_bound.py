#!/usr/bin/env python3
"""How much could a spatial prior save over the previous-Gaussian reference?

An upper bound for any position-driven prior (a hash grid with a context MLP, as in HAC,
included) on an Inria 3DGS PLY: each attribute group is quantized with a fine uniform step
(the near-lossless end, where the saving of a predictor does not depend on the step) and the
order-0 entropy of the integer residuals is measured against these predictions:

  none      no prediction (a factorized prior)
  prev      the previous Gaussian in Morton order (what spec §3.4's reference is)
  causal8   the mean of the 8 nearest among the previous 256 Gaussians in Morton order
  all8      the mean of the 8 nearest Gaussians, earlier or later (non-causal: no decoder can
            have it; a fitted field such as a hash grid can at best approach it, and pays for
            its parameters, which this bound ignores)
  +ctx      the same residuals coded with 8 tables chosen by the neighbours' spread (a
            mean-and-scale prior); the tables' cost is ignored, so this is optimistic

Usage: python3 tools/prior_bound.py scene.ply   (needs numpy and scipy)
Figures quoted in spec §3.8 were made with this script.
"""
import sys

import numpy as np
from scipy.spatial import cKDTree

STEPS = {"scale": 0.02, "opacity": 0.05, "rotation": 0.004, "sh_dc": 0.01, "sh_rest": 0.01}
K, WINDOW, CLASSES = 8, 256, 8


def read_ply(path):
    with open(path, "rb") as f:
        data = f.read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    n, props = 0, []
    for line in data[:end].decode().split("\n"):
        if line.startswith("element vertex"):
            n = int(line.split()[2])
        elif line.startswith("property"):
            if line.split()[1] != "float":
                sys.exit(f"{path}: only float properties are supported ({line})")
            props.append(line.split()[-1])
    arr = np.frombuffer(data[end:end + 4 * n * len(props)], dtype="<f4").reshape(n, len(props))
    return {p: arr[:, i].astype(np.float64) for i, p in enumerate(props)}, n


def morton(q):
    out = np.zeros(len(q), dtype=np.uint64)
    for b in range(16):
        for a in range(3):
            bit = (q[:, a].astype(np.uint64) >> np.uint64(b)) & np.uint64(1)
            out |= bit << np.uint64(3 * b + a)
    return out


def entropy(sym):
    """Order-0 entropy in bits per row, each column with its own table."""
    if len(sym) == 0:
        return 0.0
    bits = 0.0
    for d in range(sym.shape[1]):
        _, c = np.unique(sym[:, d], return_counts=True)
        bits += -(c * np.log2(c / c.sum())).sum()
    return bits / len(sym)


def entropy_by_context(res, spread):
    """Each column coded with CLASSES tables chosen by quantiles of its context value."""
    total = 0.0
    for d in range(res.shape[1]):
        edges = np.quantile(spread[:, d], np.linspace(0, 1, CLASSES + 1)[1:-1])
        cls = np.searchsorted(edges, spread[:, d])
        for c in range(CLASSES):
            sel = cls == c
            total += entropy(res[sel, d:d + 1]) * sel.sum()
    return total / len(res)


def groups(v):
    out = {"scale": np.stack([v[f"scale_{i}"] for i in range(3)], 1),
           "opacity": v["opacity"][:, None]}
    r = np.stack([v[f"rot_{i}"] for i in range(4)], 1)
    r /= np.linalg.norm(r, axis=1, keepdims=True)
    out["rotation"] = r * np.where(r[:, :1] < 0, -1, 1)
    out["sh_dc"] = np.stack([v[f"f_dc_{i}"] for i in range(3)], 1)
    rest = sorted((k for k in v if k.startswith("f_rest_")), key=lambda k: int(k[7:]))
    if rest:
        out["sh_rest"] = np.stack([v[k] for k in rest], 1)
    return out


def main(path):
    v, n = read_ply(path)
    pos = np.stack([v["x"], v["y"], v["z"]], 1)
    lo, hi = pos.min(0), pos.max(0)
    q = np.floor((pos - lo) / max((hi - lo).max(), 1e-30) * (2**16 - 1)).astype(np.int64)
    order = np.argsort(morton(q), kind="stable")
    pos = pos[order]
    nearest = cKDTree(pos).query(pos, k=K + 1)[1][:, 1:]
    causal = []
    for i in range(n):
        j0 = max(0, i - WINDOW)
        d = np.linalg.norm(pos[j0:i] - pos[i], axis=1)
        k = min(K, i - j0)
        causal.append(j0 + (np.argpartition(d, k - 1)[:k] if 0 < k < len(d) else np.arange(k)))
    print(f"{path}: {n} Gaussians; bits per Gaussian of the residual symbols at a fine step")
    cols = ["none", "prev", "causal8", "all8", "causal8+ctx", "all8+ctx"]
    print(f"{'group':9s}" + "".join(f"{c:>12s}" for c in cols))
    totals = np.zeros(len(cols))
    for name, x in groups(v).items():
        s = np.round(x[order] / STEPS[name]).astype(np.int64)
        prev = np.vstack([np.zeros_like(s[:1]), s[:-1]])
        cmean, cspread = np.zeros_like(s), np.zeros(s.shape)
        for i, c in enumerate(causal):
            if len(c):
                cmean[i], cspread[i] = np.round(s[c].mean(0)), s[c].std(0)
        amean, aspread = np.round(s[nearest].mean(1)).astype(np.int64), s[nearest].std(1)
        row = [entropy(s), entropy(s - prev), entropy(s - cmean), entropy(s - amean),
               entropy_by_context(s - cmean, cspread), entropy_by_context(s - amean, aspread)]
        totals += row
        print(f"{name:9s}" + "".join(f"{b:12.2f}" for b in row))
    print(f"{'total':9s}" + "".join(f"{b:12.2f}" for b in totals))


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    main(sys.argv[1])
