"""HAC's grid lookup ported to torch (independent of the exporter's numpy port): the features
HAC's context MLP sees at the anchors, to measure the resampled grid (A.7.4)."""
from __future__ import annotations

import numpy as np
import torch


def hac_features_torch(enc_sd, use_2d, p_norm):
    """HAC:submodules/gridencoder/src/gridencoder.cu:kernel_grid forward, in torch."""
    parts = []
    specs = [("encoding_xyz.", [0, 1, 2]), ("encoding_xy.", [0, 1]), ("encoding_xz.", [0, 2]),
             ("encoding_yz.", [1, 2])] if use_2d else [("", [0, 1, 2])]
    p_all = torch.from_numpy(p_norm.astype(np.float32))
    for prefix, axes in specs:
        emb_all = torch.where(enc_sd[prefix + "params"] >= 0, 1.0, -1.0)
        offs = enc_sd[prefix + "offsets_list"].tolist()
        for li, r in enumerate(enc_sd[prefix + "resolutions_list"].tolist()):
            emb = emb_all[offs[li]:offs[li + 1]]
            size = offs[li + 1] - offs[li]
            p = p_all[:, axes]
            d = len(axes)
            pos = p * (r - 2) + 0.5
            pg = torch.floor(pos).long()
            fr = pos - pg
            res = torch.zeros(len(p), emb.shape[1])
            wn = torch.zeros(len(p))
            terms = []
            for corner in range(1 << d):
                w = torch.ones(len(p))
                loc = pg.clone()
                for a in range(d):
                    if (corner >> a) & 1:
                        w = w * fr[:, a]
                        loc[:, a] = torch.clamp(pg[:, a] + 1, max=r - 1)
                    else:
                        w = w * (1 - fr[:, a])
                valid = ~((loc == 0) | (loc == r - 1)).any(1)
                if r ** d <= size:
                    idx = sum(loc[:, a] * r ** a for a in range(d))
                else:
                    idx = loc[:, 0] & 0xFFFFFFFF
                    for a, pr in zip(range(1, d), (2654435761, 805459861)):
                        idx = idx ^ ((loc[:, a] * pr) & 0xFFFFFFFF)
                idx = idx % size
                wn += torch.where(valid, w, 0.0)
                terms.append((w, idx, valid))
            wn = torch.where(wn == 0, 1e-9, wn)
            for w, idx, valid in terms:
                res += torch.where(valid, w / wn, 0.0)[:, None] * emb[idx]
            oob = ((p < 0) | (p > 1)).any(1)
            res[oob] = 0
            parts.append(res.numpy().astype(np.float64))
    return np.concatenate(parts, 1)
