"""The explicit-Gaussians profile's fixed chunks (§3): the preflight `GHED` (§3.2), the
attribute groups `GQUA` (§3.3, Table 3-3), a layer's `GLAY` (§3.4) and, in a progressive
stream (0.15), a refinement's header `GREF` (§3.8.1)."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .container import Limits, Reader
from .entropy import payload_method
from .errors import SalvqError
from .model import f32_of_bits, is_finite_bits
from .quantizers import f32_from_bits

GHED_LENGTH = 35
IDENTITY, KLT = 0, 4               # §3.3 lattice codes of this profile
GROUP_NAMES = ("scale", "opacity", "rotation", "sh_dc", "sh_rest")      # Table 3-3, g order
SCALE, OPACITY, ROTATION, SH_DC, SH_REST = range(5)
SIZE_CLASSES = 4                   # §3.5: 0 … 3 (three thresholds)
CONTEXT_CLASSES = 8                # §3.5: 0 … 7


@dataclass
class GHead:
    """`GHED` fields (Table 3-1) and what follows from them (Table 3-3)."""
    N: int
    sh_degree: int
    M: int
    head_flags: int        # bit 0: progressive (§3.8, 0.15); bits 1 – 7 reserved
    rate_mask: int
    origin_bits: list
    decoded_bytes: int

    @property
    def B(self) -> int:
        """Higher SH coefficients per colour channel."""
        return (self.sh_degree + 1) ** 2 - 1

    @property
    def G(self) -> int:
        """Number of attribute groups: no `sh_rest` when B = 0."""
        return 5 if self.B > 0 else 4

    def group_dims(self) -> list[int]:
        """d of each group g < G (Table 3-3)."""
        return [3, 1, 3, 3, 3 * self.B][:self.G]

    def group_offsets(self) -> list[int]:
        """Index of group g's first coded value v (groups in order)."""
        offs, o = [], 0
        for d in self.group_dims():
            offs.append(o)
            o += d
        return offs

    @property
    def D(self) -> int:
        """Coded values per Gaussian."""
        return sum(self.group_dims())

    def decoded_size(self) -> int:
        """§3.2 step 5: 4 · N · (14 + 3B), the bytes of Table 3-4's float tensors."""
        return 4 * self.N * (14 + 3 * self.B)

    def coded_rates(self) -> list[int]:
        return [r for r in range(64) if (self.rate_mask >> r) & 1]

    @property
    def progressive(self) -> bool:
        """`head_flags` bit 0 (§3.2, §3.8): the coarsest coded rate as a full layer, then each
        finer one as a refinement of the rate before it."""
        return bool(self.head_flags & 1)

    def layer_rates(self) -> list[int]:
        """The rate of each layer in stream order (§3.7): increasing in a layered stream,
        decreasing in a progressive one (layer 0 the highest set bit of `rate_mask`)."""
        rates = self.coded_rates()
        return rates[::-1] if self.progressive else rates

    def origin(self) -> np.ndarray:
        return np.array(self.origin_bits, np.uint32).view(np.float32)


def parse_ghed(payload: bytes, limits: Limits) -> GHead:
    """§3.2 steps 1-6 (step 7, the selected rate, is the caller's)."""
    def short():
        raise SalvqError("Truncated", f"GHED payload too short ({len(payload)} bytes) "
                                      "(structure: GHED payload) [§3.2]")

    r = Reader(payload, 0, short)
    h = GHead(N=r.u32(), sh_degree=r.u8(), M=r.u8(), head_flags=r.u8(), rate_mask=r.u64(),
              origin_bits=[r.u32(), r.u32(), r.u32()], decoded_bytes=r.u64())      # step 1
    if r.remaining() != 0:                                                         # step 2
        raise SalvqError("ChunkSizeMismatch",
                         f"chunk GHED: payload length {len(payload)}, expected {GHED_LENGTH} [§3.2]")
    if h.head_flags & 0xFE:                                                        # step 3
        raise SalvqError("ReservedBitsSet",
                         f"GHED head_flags = 0x{h.head_flags:02x}: reserved bits 1 – 7 set [§3.2]")

    def rng(name, v, lo, hi):                                                      # step 4
        if not lo <= v <= hi:
            raise SalvqError("FieldOutOfRange", f"GHED field {name} = {v}, range {lo} … {hi} [§3.2]")

    rng("gaussian_count", h.N, 1, (1 << 32) - 1)
    rng("sh_degree", h.sh_degree, 0, 3)
    rng("rate_count", h.M, 1, 64)
    if h.rate_mask == 0 or h.rate_mask >> h.M:
        raise SalvqError("FieldOutOfRange",
                         f"GHED field rate_mask = 0x{h.rate_mask:x}: must be non-zero with no bit ≥ {h.M} [§3.2]")
    for i in range(3):
        if not is_finite_bits(h.origin_bits[i]):
            raise SalvqError("NonFiniteValue", f"GHED.origin[{i}]: value is not finite [§3.2]")
    size = h.decoded_size()                                                        # step 5
    if h.decoded_bytes != size:
        raise SalvqError("DecodedSizeMismatch",
                         f"GHED decoded_bytes = {h.decoded_bytes}, the fields imply {size} [§3.2]")
    if h.N > limits.anchors:                                                       # step 6
        raise SalvqError("LimitExceeded", f"anchors (Gaussians): requested {h.N}, allowed {limits.anchors} [§9.1]")
    # §9.1: what the decode holds besides its output; this decoder always keeps the symbols
    # (the canonical form): voxels, D coded values, rotation index, size class, refinement.
    d = 10 + 3 * ((h.sh_degree + 1) ** 2 - 1)
    held = size + h.N * (12 + 4 * d + 14)
    if held > limits.allocation_bytes:
        raise SalvqError("LimitExceeded",
                         f"allocation bytes: requested {held}, allowed {limits.allocation_bytes} [§9.1]")
    return h


@dataclass
class GGroup:
    """One attribute group of `GQUA` (§3.3)."""
    g: int
    d: int
    lattice: int
    step: np.float32
    gains: np.ndarray                 # [M] f32
    mean: np.ndarray                  # [d] f32
    matrix: np.ndarray | None = None  # B = U·diag(s) (lattice 4), None for the identity

    @property
    def name(self) -> str:
        return GROUP_NAMES[self.g]

    def base_step(self, rate: int) -> np.float32:
        """G_{g,r} = step ⊗ gain_r, one binary32 multiplication."""
        with np.errstate(over="ignore", under="ignore"):
            return np.float32(self.step * self.gains[rate])


def parse_gqua(payload: bytes, h: GHead) -> list[GGroup]:
    """§3.3: §1.6 steps 1-2, then each group's fields, each checked as it is read."""
    payload_method("GQUA", payload, 0)

    def short():
        raise SalvqError("Truncated", f"GQUA payload too short ({len(payload)} bytes) "
                                      "(structure: GQUA payload) [§3.3]")

    r = Reader(payload, 1, short)

    def f32(name: str, idx: str) -> np.float32:
        bits = r.u32()
        if not is_finite_bits(bits):
            raise SalvqError("NonFiniteValue", f"{name}[{idx}]: value is not finite [§3.3]")
        return f32_from_bits(bits)

    def positive(name: str, idx: str, v: np.float32) -> None:
        if not v > 0:             # −0.0 included
            raise SalvqError("ValueNotPositive", f"{name}[{idx}]: value is not > 0 [§3.3]")

    def f16s(name: str, g: int, n: int) -> np.ndarray:
        # value by value: the values present are checked before a short payload is reported
        present = min(n, r.remaining() // 2)
        raw = np.frombuffer(payload, "<u2", present, r.pos)
        bad = np.nonzero((raw & 0x7C00) == 0x7C00)[0]      # binary16 ±inf and NaN
        if bad.size:
            raise SalvqError("NonFiniteValue", f"{name}[{g}, {int(bad[0])}]: value is not finite [§3.3]")
        raw = np.frombuffer(r.take(2 * n), "<u2")
        return raw.view("<f2").astype(np.float32)          # exact widening (§0.2)

    groups = []
    for g, d in enumerate(h.group_dims()):
        lattice = r.u8()
        if lattice not in (IDENTITY, KLT):
            raise SalvqError("ValueInvalid", f"GQUA.lattice[{g}] = {lattice}: must be 0 or 4 [§3.3]")
        step = f32("GQUA.step", f"{g}")
        positive("GQUA.step", f"{g}", step)
        gains = np.empty(h.M, np.float32)
        for i in range(h.M):
            gains[i] = f32("GQUA.gains", f"{g}, {i}")
            positive("GQUA.gains", f"{g}, {i}", gains[i])
        grp = GGroup(g, d, lattice, step, gains, np.empty(d, np.float32))
        for i in range(h.M):
            G = grp.base_step(i)
            if not np.isfinite(G):
                raise SalvqError("NonFiniteValue", f"GQUA.gains[{g}, {i}]: step ⊗ gain overflows binary32 [§3.3]")
            if G == 0:
                raise SalvqError("ValueNotPositive", f"GQUA.gains[{g}, {i}]: step ⊗ gain underflows to 0 [§3.3]")
        for j in range(d):
            grp.mean[j] = f32("GQUA.mean", f"{g}, {j}")
        if lattice == KLT:
            U = f16s("GQUA.basis_u", g, d * d).reshape(d, d)   # U[i][j] = basis_u[i·d + j]
            s = f16s("GQUA.basis_s", g, d)
            zero = np.nonzero(s == 0)[0]                      # +0 or −0
            if zero.size:
                raise SalvqError("BasisSingular",
                                 f"GQUA.basis_s[{g}, {int(zero[0])}] = 0: the basis is singular [§3.3]")
            grp.matrix = (U * s[None, :]).astype(np.float32)   # B[i][j] = U[i][j] ⊗ s_j (exact)
        groups.append(grp)
    if r.remaining() != 0:
        raise SalvqError("ChunkSizeMismatch",
                         f"chunk GQUA: payload length {len(payload)}, the groups end at {r.pos} [§3.3]")
    return groups


@dataclass
class GLayer:
    """`GLAY` fields (§3.4)."""
    coord_bits: int
    voxel_size: np.float32
    pred_level: int
    rotation_freq: list
    size_threshold: list
    refine: list
    shift: list = field(default_factory=list)         # shift[g - 1][c]
    scale_offset: list = field(default_factory=list)  # scale_offset[g - 1][c]
    predict: list = field(default_factory=list)       # predict[g]
    scale_table: list = field(default_factory=list)   # scale_table[v][x], 0 … 127 (0.14)
    rest_count_freq: list = field(default_factory=list)  # node m of the sh_rest count's tree at m − 1


def rest_count_bits(h: GHead) -> int:
    """L = bitlen(d) for the sh_rest group's d = 3B values (§3.5); 0 without the group."""
    return (h.D - 10).bit_length() if h.G == 5 else 0


def glay_length(h: GHead) -> int:
    """Payload length: coding_method, 28 bytes of fixed fields, shift, scale_offset, predict,
    rest_count_freq, scale_table. (§3.4 writes `1 + 25 + …`; the fixed fields take
    1 + 4 + 1 + 6 + 12 + 4 = 28 bytes, as the vectors' `GLAY` lengths confirm.)"""
    nodes = (1 << rest_count_bits(h)) - 1
    return 1 + 28 + 2 * SIZE_CLASSES * (h.G - 1) + h.G + 2 * nodes + CONTEXT_CLASSES * h.D


def parse_glay(payload: bytes, h: GHead) -> GLayer:
    """§3.4: §1.6 steps 1-2, the length, then the fields in stream order."""
    payload_method("GLAY", payload, 0)
    expected = glay_length(h)
    if len(payload) != expected:
        raise SalvqError("ChunkSizeMismatch",
                         f"chunk GLAY: payload length {len(payload)}, expected {expected} [§3.4]")
    r = Reader(payload, 1)

    def rng(name, v, lo, hi):
        if not lo <= v <= hi:
            raise SalvqError("FieldOutOfRange", f"GLAY field {name} = {v}, range {lo} … {hi} [§3.4]")

    coord_bits = r.u8()
    rng("coord_bits", coord_bits, 1, 21)
    vbits = r.u32()
    if not is_finite_bits(vbits):
        raise SalvqError("NonFiniteValue", "GLAY.voxel_size[0]: value is not finite [§3.4]")
    if not f32_of_bits(vbits) > 0:
        raise SalvqError("ValueNotPositive", "GLAY.voxel_size[0]: value is not > 0 [§3.4]")
    pred_level = r.u8()
    rng("pred_level", pred_level, 0, coord_bits)
    rotation_freq = [r.u16() for _ in range(3)]
    for i, f in enumerate(rotation_freq):
        rng(f"rotation_freq[{i}]", f, 1, 65535)
    size_threshold = []
    for c in range(3):
        t = int.from_bytes(r.take(4), "little", signed=True)
        if size_threshold and t < size_threshold[-1]:
            raise SalvqError("ValueInvalid",
                             f"GLAY.size_threshold[{c}] = {t} is below size_threshold[{c - 1}] = "
                             f"{size_threshold[-1]} [§3.4]")
        size_threshold.append(t)
    refine = [r.u8() for _ in range(SIZE_CLASSES)]
    for c, e in enumerate(refine):
        rng(f"refine[{c}]", e, 0, 24 - coord_bits)

    def per_class(name: str, bound: int) -> list:
        """An i8 table [g − 1][c] for the groups g ≥ 1, each entry within ±bound."""
        rows = []
        for g in range(1, h.G):
            row = []
            for c in range(SIZE_CLASSES):
                v = int.from_bytes(r.take(1), "little", signed=True)
                if not -bound <= v <= bound:
                    raise SalvqError("ValueInvalid",
                                     f"GLAY.{name}[{g - 1}, {c}] = {v}, range −{bound} … {bound} [§3.4]")
                row.append(v)
            rows.append(row)
        return rows

    shift = per_class("shift", 16)
    scale_offset = per_class("scale_offset", 63)
    predict = [r.u8() for _ in range(h.G)]
    for g, p in enumerate(predict):
        rng(f"predict[{g}]", p, 0, 1)
    rest_count_freq = []
    for m in range((1 << rest_count_bits(h)) - 1):
        rest_count_freq.append(r.u16())
        rng(f"rest_count_freq[{m}]", rest_count_freq[-1], 1, 65535)
    table = r.take(CONTEXT_CLASSES * h.D)
    for i, k in enumerate(table):          # 0 … 127 since 0.14 (from 64 wide scales, §6.3.6)
        rng(f"scale_table[{i // CONTEXT_CLASSES}][{i % CONTEXT_CLASSES}]", k, 0, 127)
    scale_table = [list(table[v * CONTEXT_CLASSES:(v + 1) * CONTEXT_CLASSES]) for v in range(h.D)]
    return GLayer(coord_bits, f32_from_bits(vbits), pred_level, rotation_freq, size_threshold,
                  refine, shift, scale_offset, predict, scale_table, rest_count_freq)


@dataclass
class GRefine:
    """`GREF` fields (§3.8.1): a refinement's header."""
    pred_level: int
    refine: list                                        # refine[c]: position bits added
    factor: list = field(default_factory=list)          # factor[g][c], 1 … 255
    scale_offset: list = field(default_factory=list)    # scale_offset[g][c], every group
    predict: list = field(default_factory=list)         # predict[g]
    rest_count_freq: list = field(default_factory=list)  # as GLayer's (§3.4, §3.5)
    scale_table: list = field(default_factory=list)     # scale_table[v][x], x of §3.8.2


def gref_length(h: GHead) -> int:
    """Payload length `1 + 5 + 9·G + 2·(2^L − 1) + 8·D` (§3.8.1): coding_method, pred_level,
    refine[4], factor[4·G], scale_offset[4·G], predict[G], rest_count_freq, scale_table."""
    nodes = (1 << rest_count_bits(h)) - 1
    return 1 + 1 + SIZE_CLASSES + 2 * SIZE_CLASSES * h.G + h.G + 2 * nodes + CONTEXT_CLASSES * h.D


def parse_gref(payload: bytes, h: GHead, coord_bits: int, E: list) -> GRefine:
    """§3.8.1: §1.6 steps 1-2, the length, then the fields in stream order, each checked as it
    is read (steps 1-7). `coord_bits` is the full layer's, E[c] the position bits below a
    voxel before this refinement (§3.8.3)."""
    payload_method("GREF", payload, 0)
    expected = gref_length(h)
    if len(payload) != expected:
        raise SalvqError("ChunkSizeMismatch",
                         f"chunk GREF: payload length {len(payload)}, expected {expected} [§3.8.1]")
    r = Reader(payload, 1)

    def rng(name, v, lo, hi):
        if not lo <= v <= hi:
            raise SalvqError("FieldOutOfRange", f"GREF field {name} = {v}, range {lo} … {hi} [§3.8.1]")

    pred_level = r.u8()                                                          # step 1
    rng("pred_level", pred_level, 0, coord_bits)
    refine = [r.u8() for _ in range(SIZE_CLASSES)]                               # step 2
    for c, e in enumerate(refine):
        rng(f"refine[{c}]", e, 0, 24 - coord_bits - E[c])
    factor = []                                                                  # step 3
    for g in range(h.G):
        row = [r.u8() for _ in range(SIZE_CLASSES)]
        for c, m in enumerate(row):
            rng(f"factor[{g}][{c}]", m, 1, 255)
        factor.append(row)
    scale_offset = []                                                            # step 4
    for g in range(h.G):
        row = []
        for c in range(SIZE_CLASSES):
            v = int.from_bytes(r.take(1), "little", signed=True)
            if not -63 <= v <= 63:
                raise SalvqError("ValueInvalid",
                                 f"GREF.scale_offset[{g}, {c}] = {v}, range −63 … 63 [§3.8.1]")
            row.append(v)
        scale_offset.append(row)
    predict = [r.u8() for _ in range(h.G)]                                       # step 5
    for g, p in enumerate(predict):
        rng(f"predict[{g}]", p, 0, 1)
    rest_count_freq = []                                                         # step 6
    for m in range((1 << rest_count_bits(h)) - 1):
        rest_count_freq.append(r.u16())
        rng(f"rest_count_freq[{m}]", rest_count_freq[-1], 1, 65535)
    table = r.take(CONTEXT_CLASSES * h.D)                                        # step 7
    for i, k in enumerate(table):
        rng(f"scale_table[{i // CONTEXT_CLASSES}][{i % CONTEXT_CLASSES}]", k, 0, 127)
    scale_table = [list(table[v * CONTEXT_CLASSES:(v + 1) * CONTEXT_CLASSES]) for v in range(h.D)]
    return GRefine(pred_level, refine, factor, scale_offset, predict, rest_count_freq, scale_table)
