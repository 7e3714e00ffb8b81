"""The scene model (§2): dimensions (§2.1, Table 2-0), the tensors of Table 2-1 and the
decoded size they imply (§1.4 step 5), the hash-grid level layout (§2.4), and the `HEAD`
preflight (§1.4)."""
from __future__ import annotations

import struct
from dataclasses import dataclass, field

from .container import Limits, Reader
from .errors import SalvqError

# Lattice codes, Table 7-1.
IDENTITY, DN, E8, GENERAL = 0, 1, 2, 3
LATTICE_NAMES = {IDENTITY: "identity", DN: "D_n", E8: "E8 product", GENERAL: "general"}


def is_finite_bits(bits: int) -> bool:
    return (bits >> 23) & 0xFF != 0xFF


def f32_of_bits(bits: int) -> float:
    return struct.unpack("<f", bits.to_bytes(4, "little"))[0]


def level_entries(r: int, d: int, t: int) -> int:
    """§2.4: E(r, d, T) = min((r + 1)^d, 2^T)."""
    return min((r + 1) ** d, 1 << t)


@dataclass
class Dims:
    """`HEAD` fields (Table 1-4) and the derived dimensions of §2.1."""
    N: int
    F: int
    K: int
    S: int
    M: int
    coord_bits: int
    head_flags: int
    feat_lattice: int
    scaling_lattice: int
    feat_regions: int
    scaling_regions: int
    C: int
    L3: int
    L2: int
    T3: int
    T2: int
    H: int
    Hs: int
    V: int
    rate_mask: int
    origin_bits: list
    voxel_size_bits: int
    res3: list = field(default_factory=list)
    res2: list = field(default_factory=list)
    decoded_bytes: int = 0

    @property
    def Cin(self) -> int:
        return self.C * (self.L3 + 3 * self.L2)

    @property
    def Cout(self) -> int:
        return 2 * (self.F + self.S + 3 * self.K) + 3

    @property
    def E3(self) -> int:
        return sum(level_entries(r, 3, self.T3) for r in self.res3)

    @property
    def E2(self) -> int:
        return sum(level_entries(r, 2, self.T2) for r in self.res2)

    def coded_rates(self) -> list[int]:
        return [r for r in range(64) if (self.rate_mask >> r) & 1]

    def group_dim(self, group: str) -> int:
        return {"feat": self.F, "scaling": self.S, "offsets": 3}[group]

    def group_lattice(self, group: str) -> int:
        return {"feat": self.feat_lattice, "scaling": self.scaling_lattice, "offsets": IDENTITY}[group]

    def group_regions(self, group: str) -> int:
        return {"feat": self.feat_regions, "scaling": self.scaling_regions, "offsets": 1}[group]

    def tensor_specs(self) -> list[tuple[str, str, tuple]]:
        """Table 2-1: (name, dtype, shape) of every present tensor, in table order."""
        N, F, K, S, M = self.N, self.F, self.K, self.S, self.M
        specs = [
            ("geometry.origin", "F32", (3,)),
            ("geometry.voxel_size", "F32", (1,)),
            ("anchor.voxel", "I32", (N, 3)),
            ("anchor.mask", "U8", (N, K)),
            ("anchor.feat", "F32", (N, F)),
            ("anchor.scaling", "F32", (N, S)),
            ("anchor.offsets", "F32", (N, K, 3)),
            ("hyperprior.resolutions_3d", "I32", (self.L3,)),
            ("hyperprior.resolutions_2d", "I32", (self.L2,)),
            ("hyperprior.log2_size", "I32", (2,)),
            ("hyperprior.grid_3d", "I8", (self.E3, self.C)),
            ("hyperprior.grid_xy", "I8", (self.E2, self.C)),
            ("hyperprior.grid_xz", "I8", (self.E2, self.C)),
            ("hyperprior.grid_yz", "I8", (self.E2, self.C)),
            ("mlp_grid.0.weight", "F32", (self.H, self.Cin)),
            ("mlp_grid.0.bias", "F32", (self.H,)),
            ("mlp_grid.2.weight", "F32", (self.Cout, self.H)),
            ("mlp_grid.2.bias", "F32", (self.Cout,)),
        ]
        for name, out in (("mlp_opacity", K), ("mlp_cov", 7 * K), ("mlp_color", 3 * K)):
            specs += [
                (f"{name}.0.weight", "F32", (self.Hs, F + self.V)),
                (f"{name}.0.bias", "F32", (self.Hs,)),
                (f"{name}.2.weight", "F32", (out, self.Hs)),
                (f"{name}.2.bias", "F32", (out,)),
            ]
        for group, d, lat, reg in (("feat", F, self.feat_lattice, self.feat_regions),
                                   ("scaling", S, self.scaling_lattice, self.scaling_regions)):
            specs += [(f"quant.{group}.step", "F32", (1,)), (f"quant.{group}.gains", "F32", (M,))]
            if lat == GENERAL:
                specs += [(f"quant.{group}.basis_u", "F32", (d, d)),
                          (f"quant.{group}.basis_s", "F32", (d,)),
                          (f"quant.{group}.basis_v", "F32", (d, d))]
            if reg > 1:
                specs += [(f"quant.{group}.regions.start", "I32", (reg - 1,)),
                          (f"quant.{group}.regions.basis_u", "F32", (reg - 1, d, d)),
                          (f"quant.{group}.regions.basis_s", "F32", (reg - 1, d)),
                          (f"quant.{group}.regions.basis_v", "F32", (reg - 1, d, d))]
        specs += [("quant.offsets.step", "F32", (1,)), ("quant.offsets.gains", "F32", (M,))]
        return specs

    def decoded_size(self) -> int:
        """§1.4 step 5 / §2.3: sum of element count x element size over Table 2-1."""
        size = {"F32": 4, "I32": 4, "U8": 1, "I8": 1}
        total = 0
        for _, dt, shape in self.tensor_specs():
            n = 1
            for s in shape:
                n *= s
            total += n * size[dt]
        return total


def _lattice_fits(code: int, d: int) -> bool:
    if code == DN:
        return d >= 2
    if code == E8:
        return d % 8 == 0
    return True


def parse_head(payload: bytes, limits: Limits) -> Dims:
    """§1.4 decoding process, steps 1-6."""
    def short():
        raise SalvqError("Truncated", f"HEAD payload too short ({len(payload)} bytes) "
                                      "(structure: HEAD payload) [§1.4]")

    r = Reader(payload, 0, short)
    # step 1
    d = Dims(
        N=r.u32(), F=r.u16(), K=r.u16(), S=r.u16(), M=r.u8(), coord_bits=r.u8(),
        head_flags=r.u8(), feat_lattice=r.u8(), scaling_lattice=r.u8(),
        feat_regions=r.u16(), scaling_regions=r.u16(), C=r.u8(), L3=r.u8(), L2=r.u8(),
        T3=r.u8(), T2=r.u8(), H=r.u16(), Hs=r.u16(), V=r.u8(), rate_mask=r.u64(),
        origin_bits=[r.u32(), r.u32(), r.u32()], voxel_size_bits=r.u32(),
    )
    # step 2
    if d.head_flags != 0:
        raise SalvqError("ReservedBitsSet", f"head_flags = 0x{d.head_flags:02x}: reserved bits set [§1.4]")
    # step 3
    d.res3 = [r.u16() for _ in range(d.L3)]
    d.res2 = [r.u16() for _ in range(d.L2)]
    d.decoded_bytes = r.u64()
    if r.remaining() != 0:
        raise SalvqError("ChunkSizeMismatch",
                         f"chunk HEAD: payload length {len(payload)}, expected {r.pos} [§1.4]")

    # step 4
    def rng(name, v, lo, hi):
        if not lo <= v <= hi:
            raise SalvqError("FieldOutOfRange", f"HEAD field {name} = {v}, range {lo} … {hi} [§1.4]")

    rng("anchor_count", d.N, 1, (1 << 32) - 1)
    rng("feat_dim", d.F, 1, 1024)
    rng("offset_count", d.K, 1, 256)
    rng("scaling_dim", d.S, 1, 64)
    rng("rate_count", d.M, 1, 64)
    rng("grid_channels", d.C, 1, 16)
    rng("levels_3d", d.L3, 0, 32)
    rng("levels_2d", d.L2, 0, 32)
    rng("log2_size_3d", d.T3, 1, 24)
    rng("log2_size_2d", d.T2, 1, 24)
    for i, v in enumerate(d.res3):
        rng(f"resolution_3d[{i}]", v, 1, 65535)
    for i, v in enumerate(d.res2):
        rng(f"resolution_2d[{i}]", v, 1, 65535)
    rng("context_input_dim", d.Cin, 1, 2048)
    rng("context_hidden", d.H, 1, 4096)
    rng("scaffold_hidden", d.Hs, 1, 4096)
    rng("view_dims", d.V, 0, 8)
    rng("coord_bits", d.coord_bits, 1, 21)
    rng("feat_lattice", d.feat_lattice, 0, 3)
    rng("scaling_lattice", d.scaling_lattice, 0, 3)
    if not _lattice_fits(d.feat_lattice, d.F):
        raise SalvqError("LatticeDimension",
                         f"HEAD feat_lattice {LATTICE_NAMES[d.feat_lattice]} does not fit F = {d.F} [§7.1]")
    if not _lattice_fits(d.scaling_lattice, d.S):
        raise SalvqError("LatticeDimension",
                         f"HEAD scaling_lattice {LATTICE_NAMES[d.scaling_lattice]} does not fit S = {d.S} [§7.1]")
    for name, lat, reg in (("feat_regions", d.feat_lattice, d.feat_regions),
                           ("scaling_regions", d.scaling_lattice, d.scaling_regions)):
        hi = min(d.N, 65535) if lat == GENERAL else 1
        rng(name, reg, 1, hi)
    if d.rate_mask == 0 or d.rate_mask >> d.M:
        raise SalvqError("FieldOutOfRange",
                         f"HEAD field rate_mask = 0x{d.rate_mask:x}: must be non-zero with no bit ≥ {d.M} [§1.4]")
    for i in range(3):
        if not is_finite_bits(d.origin_bits[i]):
            raise SalvqError("NonFiniteValue", f"geometry.origin[{i}]: value is not finite [§1.4]")
    if not is_finite_bits(d.voxel_size_bits):
        raise SalvqError("NonFiniteValue", "geometry.voxel_size[0]: value is not finite [§1.4]")
    if not f32_of_bits(d.voxel_size_bits) > 0:
        raise SalvqError("ValueNotPositive", "geometry.voxel_size[0]: value is not > 0 [§1.4]")
    # step 5
    size = d.decoded_size()
    if size != d.decoded_bytes:
        raise SalvqError("DecodedSizeMismatch",
                         f"HEAD decoded_bytes = {d.decoded_bytes}, the dimensions imply {size} [§1.4]")
    # step 6
    if d.N > limits.anchors:
        raise SalvqError("LimitExceeded", f"anchors: requested {d.N}, allowed {limits.anchors} [§9.1]")
    if size > limits.allocation_bytes:
        raise SalvqError("LimitExceeded",
                         f"allocation bytes: requested {size}, allowed {limits.allocation_bytes} [§9.1]")
    return d
