"""What §6.3.6's wide scales cost (spec §6.5, informative), from spec/tables/gaussian_tables.txt.

u = round(N(0, σ²)) with σ log-uniform in each range (2^18 draws, seed 2026), coded at the
scale index nearest σ on the grid of §6.3.1 continued (k = round(8 log2 σ + 24), at most 127).
Prints the ideal bits against −log2 of u's true discretized-Gaussian mass: at σ_k itself (the
grid's own loss), with wide scales, and at k = 63 with escapes (no wide scales).

    python3 python/tools/wide_scale_overhead.py
"""
import math
import os

import numpy as np
from math import erf
class norm:
    @staticmethod
    def cdf(x):
        return 0.5 * (1 + _erf(x / math.sqrt(2)))
_erf = np.vectorize(erf)
rows = {}
for line in open(os.path.join(os.path.dirname(__file__), '..', '..', 'spec', 'tables', 'gaussian_tables.txt')):
    if line.startswith('#'): continue
    f = line.split(); k = int(f[0]); R = int(f[3]); fr = np.array([int(x) for x in f[4:]])
    rows[k] = (R, fr)
def table_bits(k, u):
    R, fr = rows[k]
    u = np.asarray(u); m = np.abs(u)
    inside = m <= R
    out = np.empty(u.shape)
    out[inside] = 16 - np.log2(fr[(u[inside] + R)])
    w = m[~inside] - R
    L = np.floor(np.log2(w))
    out[~inside] = 16 - math.log2(fr[2*R+1]) + 2*L + 2
    return out
def wide_bits(k, u):
    if k < 64: return table_bits(k, u)
    b = (k - 56) // 8; t = k - 8*b
    return table_bits(t, np.floor_divide(u, 2**b)) + b
rng = np.random.default_rng(2026)
n = 1 << 18
for lo, hi in [(32, 7512), (32, 128), (128, 1024), (1024, 7512)]:
    sig = np.exp(rng.uniform(math.log(lo), math.log(hi), n))
    u = np.round(rng.normal(0, sig)).astype(np.int64)
    true = -np.log2(norm.cdf((u + .5)/sig) - norm.cdf((u - .5)/sig))
    # the index §6.3.1's thresholds would give, continued: nearest k on the 8-per-octave grid
    k = np.clip(np.floor(8*np.log2(sig) + 24 + 0.5), 0, 127).astype(int)
    grid = -np.log2(norm.cdf((u + .5)/2**((k-24)/8)) - norm.cdf((u - .5)/2**((k-24)/8)))
    wide = np.zeros(n); old = np.zeros(n)
    for kk in np.unique(k):
        s = k == kk
        wide[s] = wide_bits(kk, u[s]); old[s] = table_bits(min(kk, 63), u[s])
    print(f"sigma {lo}-{hi}: true {true.mean():.3f} bits; grid {100*(grid.sum()/true.sum()-1):.3f} %; wide {100*(wide.sum()/true.sum()-1):.3f} % (beyond grid {100*(wide.sum()/grid.sum()-1):.3f} %); k=63 with escapes {100*(old.sum()/true.sum()-1):.1f} %, escaped {100*np.mean(np.abs(u) > 127):.1f} %")
