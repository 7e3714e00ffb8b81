"""Spec §5 from the decoded model and the stream, written independently of the encoder: the
MLPS chunk (§1.6.2, Table 5-1), the grid features and touched entries (§5.1, §5.2), and each
anchor's step (§5.3, §5.4)."""
from __future__ import annotations

import numpy as np

from .harness import ROOT


def read_step_factor():
    tab = {}
    for line in (ROOT / "spec" / "tables" / "step_factor.txt").read_text().splitlines():
        if line and not line.startswith("#"):
            a, v = line.split()
            tab[int(a)] = int(v)
    return np.array([tab[a] for a in range(-64, 65)], np.int64)


def rshr(a: int, s: int) -> int:
    return a if s == 0 else (a + (1 << (s - 1))) >> s


def parse_mlps(stream: bytes, info: dict, cin: int, h: int, cout: int):
    """§1.6.2 / Table 5-1 from the stream's MLPS chunk (offset from `salvq info --json`),
    format 0.10: `context_precision` first (Table 1-7: 0 = i16, 1 = i8 `w0`/`w1`, both the same
    §5.3 integers), then the integer context MLP, then `scaffold_precision` (Table 1-6)."""
    ch = next(c for c in info["chunks"] if c["tag"] == "MLPS")
    body = stream[ch["offset"] + 8 + 1: ch["offset"] + 8 + ch["payload_bytes"]]
    cprec = body[0]
    if cprec not in (0, 1):
        raise ValueError(f"MLPS context_precision = {cprec}, Table 1-7 defines 0 and 1")
    w, wdt = (2, "<i2") if cprec == 0 else (1, "i1")
    a0, shift0 = body[1], body[2]
    a1 = np.frombuffer(body, np.uint8, cout, 3).astype(np.int64)
    o = 3 + cout
    w0 = np.frombuffer(body, wdt, h * cin, o).astype(np.int64).reshape(h, cin)
    o += w * h * cin
    b0 = np.frombuffer(body, "<i4", h, o).astype(np.int64)
    o += 4 * h
    w1 = np.frombuffer(body, wdt, cout * h, o).astype(np.int64).reshape(cout, h)
    o += w * cout * h
    b1 = np.frombuffer(body, "<i4", cout, o).astype(np.int64)
    o += 4 * cout                      # o = context(w), the offset of scaffold_precision
    return dict(a0=a0, shift0=shift0, a1=a1, w0=w0, b0=b0, w1=w1, b1=b1, precision=body[o],
                context_precision=cprec)


def spec_entry(loc, r, t):
    d = loc.shape[1]
    if (r + 1) ** d <= 1 << t:
        return sum(loc[:, a] * (r + 1) ** a for a in range(d))
    h = loc[:, 0].astype(np.uint64)
    for a, p in zip(range(1, d), (2654435761, 805459861)):
        h ^= (loc[:, a].astype(np.uint64) * np.uint64(p)) & np.uint64(0xFFFFFFFF)
    return (h % np.uint64(1 << t)).astype(np.int64)


def spec_levels(model):
    r3 = model["hyperprior.resolutions_3d"].tolist()
    r2 = model["hyperprior.resolutions_2d"].tolist()
    t3, t2 = model["hyperprior.log2_size"].tolist()
    out = []
    for tensor, axes, res, t in (("grid_3d", (0, 1, 2), r3, t3), ("grid_xy", (0, 1), r2, t2),
                                 ("grid_xz", (0, 2), r2, t2), ("grid_yz", (1, 2), r2, t2)):
        start = 0
        for r in res:
            e = min((r + 1) ** len(axes), 1 << t)
            out.append((tensor, axes, r, t, start, e))
            start += e
    return out


def spec_features(model, vox, bits):
    """§5.1: integer grid features (units 2^-8) and the touched entries (§5.2)."""
    feats, touched = [], {}
    for tensor, axes, r, t, start, e in spec_levels(model):
        g = model["hyperprior." + tensor][start:start + e].astype(np.int64)
        d = len(axes)
        cw = []
        for a in axes:
            x = (2 * vox[:, a] + 1) * r
            cell = x >> (bits + 1)
            frac = x & ((1 << (bits + 1)) - 1)
            w1 = frac >> (bits + 1 - 10) if bits + 1 >= 10 else frac << (10 - bits - 1)
            cw.append((cell, 1024 - w1, w1))
        acc = np.zeros((len(vox), g.shape[1]), np.int64)
        for corner in range(1 << d):
            loc = np.stack([cw[i][0] + ((corner >> i) & 1) for i in range(d)], 1)
            w = np.prod(np.stack([cw[i][2] if (corner >> i) & 1 else cw[i][1] for i in range(d)], 1), 1)
            ent = spec_entry(loc, r, t)
            touched.setdefault(tensor, set()).update((start + ent).tolist())
            acc += w[:, None] * g[ent]
        s = 22 if d == 3 else 12
        feats.append((acc + (1 << (s - 1))) >> s)
    return np.concatenate(feats, 1), touched


def spec_steps(model, vox, bits, mlps, cout, rate=0):
    """§5.3 / §5.4: each anchor's binary32 step Delta for the three groups."""
    x, _ = spec_features(model, vox, bits)
    s = mlps["b0"][None] + x @ mlps["w0"].T
    s = ((s + 2 ** 31) % 2 ** 32) - 2 ** 31                       # i32 wrap
    sh = mlps["shift0"]
    a = np.clip(((s + (1 << (sh - 1))) >> sh) if sh else s, 0, 32767)
    sf = read_step_factor()
    qh = 8 + mlps["a0"] - sh
    out = {}
    for gi, grp in enumerate(("feat", "scaling", "offsets")):
        o = cout - 3 + gi
        y = mlps["b1"][o] + a @ mlps["w1"][o]
        y = ((y + 2 ** 31) % 2 ** 32) - 2 ** 31
        e = int(qh + mlps["a1"][o])
        idx = np.array([max(-64, min(64, rshr(16 * int(v), e) if e < 40 else 0)) for v in y])
        g32 = np.float32(model[f"quant.{grp}.step"][0]) * np.float32(model[f"quant.{grp}.gains"][rate])
        delta = (np.float32(g32) * sf[idx + 64].astype(np.float32)).astype(np.float32) * np.float32(2.0 ** -16)
        out[grp] = delta.astype(np.float64)
    return out
