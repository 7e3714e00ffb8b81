"""Quantizers (§7, §2.6): `QUAN` (§1.6.3), the lattice generators (§7.2), the general
matrix B = U diag(s) V^T in binary32 (§7.2), Sp-SALVQ regions (§7.6) and the binary32
reconstruction x = m + Δ·(B u) (§7.3, §5.5)."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .errors import SalvqError
from .model import DN, E8, GENERAL, IDENTITY, Dims

QNAN_BITS = 0x7FC00000

# Table 7-2: 2 * B[i][j] of the E8 block.
_E8_TWICE = np.array([
    [2, 2, 2, 2, 2, 1, 1, 0],
    [0, 2, 2, 2, 2, 1, 1, 0],
    [0, 0, 2, 2, 2, 1, 1, 0],
    [0, 0, 0, 2, 2, 1, 1, 0],
    [0, 0, 0, 0, 2, 1, 1, 0],
    [0, 0, 0, 0, 0, 1, 1, 0],
    [0, 0, 0, 0, 0, -1, 1, 0],
    [-2, -4, -6, -8, -10, -5, -7, 4],
], dtype=np.float32)


def generator(code: int, d: int) -> np.ndarray | None:
    """§7.2 fixed generators (None for the identity)."""
    if code == IDENTITY:
        return None
    if code == DN:
        B = np.zeros((d, d), np.float32)
        for j in range(d - 1):
            B[j, j] = 1
            B[d - 1, j] = -1
        B[d - 1, d - 1] = 2
        return B
    if code == E8:
        B = np.zeros((d, d), np.float32)
        blk = _E8_TWICE / np.float32(2)
        for b in range(d // 8):
            B[8 * b:8 * b + 8, 8 * b:8 * b + 8] = blk
        return B
    raise ValueError(code)


def general_matrix(U: np.ndarray, s: np.ndarray, V: np.ndarray) -> np.ndarray:
    """§7.2 General: a_{k+1} = a_k ⊕ ((U[i][k] ⊗ s_k) ⊗ V[j][k]), a_0 = +0, in binary32."""
    d = s.shape[0]
    acc = np.zeros((d, d), np.float32)
    with np.errstate(over="ignore", invalid="ignore"):
        us = (U * s[None, :]).astype(np.float32)        # U[i][k] ⊗ s_k
        for k in range(d):
            acc = acc + np.outer(us[:, k], V[:, k]).astype(np.float32)
    return acc


@dataclass
class Group:
    name: str
    d: int
    lattice: int
    step_bits: int
    gains_bits: list
    region_starts: list = field(default_factory=list)      # start_1 .. start_{R-1}
    bases: list = field(default_factory=list)              # [(U, s, V)] float32, region 0 first
    matrices: list = field(default_factory=list)           # B_r (None: identity)

    def G_bits(self, rate: int) -> int:
        """§5.4: G_g = step_g ⊗ gain_{g, rate}, as binary32 bits."""
        g = f32_from_bits(self.step_bits) * f32_from_bits(self.gains_bits[rate])
        return int(np.float32(g).view(np.uint32))

    def region_of(self, n: int) -> np.ndarray:
        """§7.6: region index of each anchor 0 .. n-1 (canonical order)."""
        idx = np.zeros(n, np.int64)
        for s in self.region_starts:
            idx[s:] += 1
        return idx


def f32_from_bits(bits: int) -> np.float32:
    return np.array([bits], np.uint32).view(np.float32)[0]


def quan_body_length(d: Dims) -> int:
    n = 0
    for g in ("feat", "scaling", "offsets"):
        dim = d.group_dim(g)
        n += 4 + 4 * d.M
        if d.group_lattice(g) == GENERAL:
            R = d.group_regions(g)
            n += 4 * (R - 1) + R * 4 * (2 * dim * dim + dim)
    return n


def parse_quan(body: bytes, d: Dims) -> tuple[dict, dict]:
    """§1.6.3 after the length check: returns the groups and the Table 2-1 quant tensors."""
    pos = 0

    def words(n):
        nonlocal pos
        a = np.frombuffer(body, "<u4", n, pos)
        pos += 4 * n
        return a

    def check_finite(name, bits, shape):
        bad = np.nonzero((bits & 0x7F800000) == 0x7F800000)[0]
        if bad.size:
            idx = np.unravel_index(int(bad[0]), shape)
            raise SalvqError("NonFiniteValue",
                             f"{name}[{', '.join(str(int(i)) for i in idx)}]: value is not finite [§1.6.3]")

    def positive(name, bits_val, idx):
        v = f32_from_bits(int(bits_val))
        if not v > 0:
            raise SalvqError("ValueNotPositive", f"{name}[{idx}]: value is not > 0 [§1.6.3]")

    groups = {}
    tensors = {}
    for gname in ("feat", "scaling", "offsets"):
        dim = d.group_dim(gname)
        lat = d.group_lattice(gname)
        R = d.group_regions(gname)
        base = f"quant.{gname}"
        step = words(1)
        check_finite(f"{base}.step", step, (1,))
        positive(f"{base}.step", step[0], 0)
        gains = words(d.M)
        # §1.6.3: the whole field's finiteness, then every value's sign.
        check_finite(f"{base}.gains", gains, (d.M,))
        for r in range(d.M):
            positive(f"{base}.gains", gains[r], r)
        g = Group(gname, dim, lat, int(step[0]), [int(v) for v in gains])
        with np.errstate(over="ignore", under="ignore"):
            for r in range(d.M):
                prod = f32_from_bits(g.step_bits) * f32_from_bits(g.gains_bits[r])
                if not np.isfinite(prod):
                    raise SalvqError("NonFiniteValue",
                                     f"{base}.gains[{r}]: step ⊗ gain overflows binary32 [§1.6.3]")
                if prod == 0:
                    raise SalvqError("ValueNotPositive",
                                     f"{base}.gains[{r}]: step ⊗ gain underflows to 0 [§1.6.3]")
        tensors[f"{base}.step"] = step.view("<f4").copy()
        tensors[f"{base}.gains"] = gains.view("<f4").copy()
        if lat == GENERAL:
            starts = words(R - 1)
            hi = min(d.N - 1, (1 << 31) - 1)
            prev = 0
            for i, s in enumerate(starts):
                s = int(s)
                if s <= prev or s > hi:
                    lo = prev + 1
                    raise SalvqError("FieldOutOfRange",
                                     f"QUAN field region_start[{i}] of {gname} = {s}, range {lo} … {hi} [§1.6.3]")
                prev = s
            g.region_starts = [int(s) for s in starts]
            for r in range(R):
                rn = f"{base}.basis" if r == 0 else f"{base}.regions.basis"
                ub = words(dim * dim)
                check_finite(f"{rn}_u" + ("" if r == 0 else f"[{r - 1}]"), ub, (dim, dim))
                sb = words(dim)
                check_finite(f"{rn}_s" + ("" if r == 0 else f"[{r - 1}]"), sb, (dim,))
                vb = words(dim * dim)
                check_finite(f"{rn}_v" + ("" if r == 0 else f"[{r - 1}]"), vb, (dim, dim))
                # BasisSingular once the whole basis (u, s, v) has passed the finiteness
                # checks: what the reference does; §1.6.3 can be read as "right after s"
                # (README, spec gaps).
                zero = np.nonzero((sb & 0x7FFFFFFF) == 0)[0]
                if zero.size:
                    raise SalvqError("BasisSingular",
                                     f"{rn}_s" + ("" if r == 0 else f"[{r - 1}]")
                                     + f"[{int(zero[0])}] = 0: the basis is singular [§1.6.3]")
                g.bases.append((ub.view("<f4").reshape(dim, dim).copy(), sb.view("<f4").copy(),
                                vb.view("<f4").reshape(dim, dim).copy()))
            for r, (U, s, V) in enumerate(g.bases):
                B = general_matrix(U, s, V)
                bad = np.nonzero(~np.isfinite(B).ravel())[0]
                if bad.size:
                    i, j = divmod(int(bad[0]), dim)
                    rn = f"{base}.basis_u" if r == 0 else f"{base}.regions.basis_u[{r - 1}]"
                    raise SalvqError("NonFiniteValue",
                                     f"{rn}: B[{i}, {j}] is not finite [§1.6.3]")
                g.matrices.append(B)
            U0, s0, V0 = g.bases[0]
            tensors[f"{base}.basis_u"] = U0
            tensors[f"{base}.basis_s"] = s0
            tensors[f"{base}.basis_v"] = V0
            if R > 1:
                tensors[f"{base}.regions.start"] = np.array(g.region_starts, np.int32)
                tensors[f"{base}.regions.basis_u"] = np.stack([b[0] for b in g.bases[1:]])
                tensors[f"{base}.regions.basis_s"] = np.stack([b[1] for b in g.bases[1:]])
                tensors[f"{base}.regions.basis_v"] = np.stack([b[2] for b in g.bases[1:]])
        else:
            g.matrices = [generator(lat, dim)]
        groups[gname] = g
    assert pos == len(body)
    return groups, tensors


def reconstruct(u: np.ndarray, B: np.ndarray | None, delta: np.ndarray,
                means: np.ndarray) -> np.ndarray:
    """§7.3 (and §5.5 for the identity): x_i = m_i ⊕ (Δ ⊗ z_i), z = B w, w = float32(u),
    every operation in binary32, sums in j order from +0. u [n, d] int64; delta [n] f32;
    means [n, d] f32. NaN results become 0x7FC00000."""
    w = u.astype(np.float64).astype(np.float32)     # exact int -> f64, one rounding to f32
    with np.errstate(over="ignore", invalid="ignore", under="ignore"):
        if B is None:
            z = w
        else:
            n, d = w.shape
            z = np.zeros((n, d), np.float32)
            for j in range(d):
                col = B[:, j]
                nz = col != 0
                if not nz.any():
                    continue
                wj = w[:, j]
                # terms with B[i][j] = 0 or w_j = 0 are ±0 and may be skipped (§7.3)
                z[:, nz] = z[:, nz] + (wj[:, None] * col[None, nz]).astype(np.float32)
        t = (delta[:, None] * z).astype(np.float32)
        x = (means + t).astype(np.float32)
    nan = np.isnan(x)
    if nan.any():
        xb = x.view(np.uint32)
        xb[nan] = QNAN_BITS
    return x
