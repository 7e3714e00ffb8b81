"""Anchor attribute chunks (§6.6): `AMSK` (§6.6.1) and the layer chunks `AFEA`, `ASCL`,
`AOFF` (§6.6.2), per tile (§10.2, §10.3); the prior of each anchor comes from §5."""
from __future__ import annotations

import numpy as np

from .ans import AnsDecoder, AnsFault, EscapeOverflowFault, ans_error
from .errors import SalvqError
from .hyperprior import (IntMlp, decompose, grid_features, means_f32, run_mlp, scale_indices,
                         step_index)
from .model import Dims
from .quantizers import Group, f32_from_bits, reconstruct
from .tables import P, STEP_FACTOR
from .tiles import Tile, split_tiles


def payload_method(tag: str, payload: bytes, method: int) -> None:
    """§1.6 steps 1-2."""
    if len(payload) == 0:
        raise SalvqError("ChunkSizeMismatch", f"chunk {tag}: empty payload (expected length unknown; 1) [§1.6]")
    if payload[0] != method:
        raise SalvqError("UnknownCodingMethod",
                         f"chunk {tag}: coding_method {payload[0]}, expected {method} [§1.6]")


def decode_amsk(payload: bytes, d: Dims, tiles: list[Tile], sel: list[bool] | None = None) -> np.ndarray:
    """§6.6.1: the [N, K] masks. With `sel` (a region decode, §10.3.1 step 3) only the
    selected tiles' bodies are decoded; the others are framed (§10.2) and their rows stay 0."""
    payload_method("AMSK", payload, 1)
    K = d.K
    p_one = []
    for k in range(K):
        off = 1 + 2 * k
        if off + 2 > len(payload):
            raise SalvqError("Truncated", f"chunk AMSK: payload too short for p_one[{k}] [§6.6.1]")
        p = int.from_bytes(payload[off:off + 2], "little")
        if p == 0:
            raise SalvqError("ValueInvalid", f"AMSK.p_one[{k}] = 0, range 1 … 65535 [§6.6.1]")
        p_one.append(p)
    freq = [min(max(p >> (16 - P), 1), (1 << P) - 1) for p in p_one]
    bodies = split_tiles("AMSK", payload, 1 + 2 * K, len(tiles))
    mask = np.zeros((d.N, K), np.uint8)
    for body, t in zip(bodies, tiles):
        if sel is not None and not sel[t.index]:
            continue
        try:
            dec = AnsDecoder(body)
            for i in range(t.start, t.start + t.count):
                row = mask[i]
                for k in range(K):
                    row[k] = dec.decode_binary(freq[k])
            dec.finish()
        except AnsFault as f:
            raise ans_error("AMSK", t.index, f) from None
    return mask


class Prior:
    """§5.3 - §5.5 at the selected rate for the anchors at `voxels` (every anchor, or in a
    region decode the selected ones: an anchor's prior depends only on its voxel and the
    shared model, §10)."""

    def __init__(self, d: Dims, mlp: IntMlp, groups: dict, rate: int, voxels: np.ndarray,
                 grids: dict):
        self.d = d
        F, S, K = d.F, d.S, d.K
        x = grid_features(d, voxels, grids)
        y = run_mlp(mlp, x)
        E = mlp.E
        Cout = d.Cout
        o = 0
        self.rows = {}
        for g, n in (("feat", F), ("scaling", S), ("offsets", 3 * K)):
            self.rows[g] = (o, o + n, o + n, o + 2 * n)     # mean rows, scale rows
            o += 2 * n
        alpha_row = {"feat": Cout - 3, "scaling": Cout - 2, "offsets": Cout - 1}
        N = voxels.shape[0]
        self.k = {}
        self.means = {}
        self.delta = {}
        cache: dict = {}
        for g in ("feat", "scaling", "offsets"):
            m0, m1, s0, s1 = self.rows[g]
            grp: Group = groups[g]
            G_bits = grp.G_bits(rate)
            G = f32_from_bits(G_bits)
            m, e = decompose(G_bits)
            ar = alpha_row[g]
            Ea = int(E[ar])
            E_scale = E[s0:s1]
            ks = np.empty((N, s1 - s0), np.int64)
            deltas = np.empty(N, np.float32)
            with np.errstate(over="ignore", under="ignore"):
                for i in range(N):
                    a = step_index(int(y[i, ar]), Ea)
                    factor = STEP_FACTOR[a + 64]
                    ks[i] = scale_indices(y[i, s0:s1], E_scale, m, e, factor, cache)
                    # §5.5 step 2: Δ = (G ⊗ float32(factor)) ⊗ 2^-16
                    dl = np.float32(G * np.float32(factor))
                    deltas[i] = np.float32(dl * np.float32(2.0 ** -16))
            if ks.size and (ks.min() < 0 or ks.max() > 63):
                raise SalvqError("ScaleIndexOutOfRange", "scale index outside 0 … 63 [§6.3.1]")
            self.k[g] = ks
            self.delta[g] = deltas
            self.means[g] = means_f32(y[:, m0:m1], E[m0:m1][None, :])


def decode_layer(payloads: dict, d: Dims, tiles: list[Tile], mask: np.ndarray, prior: Prior,
                 groups: dict, sel: list[bool] | None = None,
                 rows: np.ndarray | None = None) -> tuple[dict, dict]:
    """§6.6.2: the selected layer's symbols and reconstructed attributes. In a region decode
    (§10.3.1) `sel` marks the selected tiles and `rows` their anchors' canonical indices (the
    prior's rows): only those tiles' bodies are decoded, the others only framed (§10.2), and
    the output has len(rows) rows; `mask` is indexed by canonical index."""
    bodies = {}
    for tag in ("AFEA", "ASCL", "AOFF"):
        p = payloads[tag]
        payload_method(tag, p, 1)
        bodies[tag] = split_tiles(tag, p, 1, len(tiles))
    F, S, K = d.F, d.S, d.K
    if rows is None:
        rows = np.arange(d.N, dtype=np.int64)
    N = len(rows)
    u_feat = np.zeros((N, F), np.int64)
    u_scal = np.zeros((N, S), np.int64)
    u_off = np.zeros((N, K, 3), np.int64)
    kf, ksc, ko = prior.k["feat"], prior.k["scaling"], prior.k["offsets"]
    nxt = 0                                 # output row of the tile's first anchor
    for t in tiles:
        if sel is not None and not sel[t.index]:
            continue
        j0 = nxt
        nxt += t.count
        decs = {}
        for tag in ("AFEA", "ASCL", "AOFF"):
            try:
                decs[tag] = AnsDecoder(bodies[tag][t.index])
            except AnsFault as f:
                raise ans_error(tag, t.index, f) from None
        cur = "AFEA"
        try:
            da, ds, do = decs["AFEA"], decs["ASCL"], decs["AOFF"]
            for i in range(t.start, t.start + t.count):
                o = j0 + i - t.start                # the anchor's output (prior) row
                cur = "AFEA"
                krow = kf[o].tolist()
                u_feat[o] = [da.decode_symbol(k) for k in krow]
                cur = "ASCL"
                krow = ksc[o].tolist()
                u_scal[o] = [ds.decode_symbol(k) for k in krow]
                cur = "AOFF"
                krow = ko[o].tolist()
                mrow = mask[i]
                for s in range(K):
                    if mrow[s]:
                        j = 3 * s
                        u_off[o, s] = [do.decode_symbol(krow[j]), do.decode_symbol(krow[j + 1]),
                                       do.decode_symbol(krow[j + 2])]
            for tag in ("AFEA", "ASCL", "AOFF"):
                cur = tag
                decs[tag].finish()
        except AnsFault as f:
            raise ans_error(cur, t.index, f) from None
        except EscapeOverflowFault:
            raise SalvqError("EscapeOverflow",
                             f"chunk {cur}, tile {t.index}: escape prefix of 31 zero bits [§6.4]") from None
    out = {}
    for g, u in (("feat", u_feat), ("scaling", u_scal)):
        grp: Group = groups[g]
        if len(grp.matrices) > 1:
            x = np.empty(u.shape, np.float32)
            reg = grp.region_of(d.N)[rows]          # §7.6 by canonical index
            for r, B in enumerate(grp.matrices):
                sel = reg == r
                if sel.any():
                    x[sel] = reconstruct(u[sel], B, prior.delta[g][sel], prior.means[g][sel])
        else:
            x = reconstruct(u, grp.matrices[0], prior.delta[g], prior.means[g])
        out[g] = x
    off = reconstruct(u_off.reshape(N, 3 * K), None, prior.delta["offsets"], prior.means["offsets"])
    off = off.reshape(N, K, 3)
    off[mask[rows] == 0] = np.float32(0.0)
    out["offsets"] = off
    return out, {"feat": u_feat, "scaling": u_scal, "offsets": u_off}
