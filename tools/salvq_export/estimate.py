"""HAC's own float estimate of the coded bits, used to report what the grid mapping costs (A.7.4)."""
from __future__ import annotations

import numpy as np

from .common import HAC_Q_FEAT, HAC_Q_OFFSETS, HAC_Q_SCALING


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

