"""The Annex A model file: spec §2.3 value rules and the byte-canonical safetensors writer (A.1)."""
from __future__ import annotations

import json
import os
import struct
from pathlib import Path

import numpy as np

from .common import SCHEMA, ExportError


TABLE_ORDER = [
    "geometry.origin", "geometry.voxel_size", "anchor.voxel", "anchor.mask", "anchor.feat",
    "anchor.scaling", "anchor.offsets", "hyperprior.resolutions_3d",
    "hyperprior.resolutions_2d", "hyperprior.log2_size", "hyperprior.grid_3d",
    "hyperprior.grid_xy", "hyperprior.grid_xz", "hyperprior.grid_yz",
    "mlp_grid.0.weight", "mlp_grid.0.bias", "mlp_grid.2.weight", "mlp_grid.2.bias",
] + [f"{m}.{l}.{p}" for m in ("mlp_opacity", "mlp_cov", "mlp_color")
     for l in (0, 2) for p in ("weight", "bias")] + [
    "quant.feat.step", "quant.feat.gains", "quant.feat.basis_u", "quant.feat.basis_s",
    "quant.feat.basis_v", "quant.scaling.step", "quant.scaling.gains", "quant.offsets.step",
    "quant.offsets.gains",
]
DTYPES = {np.dtype(np.float32): "F32", np.dtype(np.int32): "I32", np.dtype(np.uint8): "U8",
          np.dtype(np.int8): "I8"}


def write_safetensors(path: Path, tensors: dict, feat_lattice: str) -> int:
    """spec Annex A.1, byte-canonical: compact JSON header (metadata, then Table 2-1 order),
    data contiguous in that order, header padded with spaces to a multiple of 8. Written to a
    temporary file in the same folder and renamed (no partial output)."""
    meta = {"format": "salvq-model", "schema": SCHEMA, "feat_lattice": feat_lattice,
            "scaling_lattice": "identity"}
    header = {"__metadata__": meta}
    blobs, off = [], 0
    for name in TABLE_ORDER:
        if name not in tensors:
            continue
        a = np.ascontiguousarray(tensors[name])
        raw = a.astype(a.dtype.newbyteorder("<"), copy=False).tobytes()
        header[name] = {"dtype": DTYPES[a.dtype], "shape": list(a.shape),
                        "data_offsets": [off, off + len(raw)]}
        blobs.append(raw)
        off += len(raw)
    h = json.dumps(header, separators=(",", ":")).encode()
    h += b" " * (-len(h) % 8)
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    try:
        with open(tmp, "wb") as fh:
            fh.write(struct.pack("<Q", len(h)))
            fh.write(h)
            for b in blobs:
                fh.write(b)
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()
    return 8 + len(h) + off


def validate(t: dict):
    """The value rules of spec §2.3 / §2.6 / Annex A.2 step 4-5 that a checkpoint can break,
    checked here so that the message names the checkpoint's tensor."""
    for name in TABLE_ORDER:
        a = t.get(name)
        if a is None:
            continue
        if a.dtype == np.float32 and not np.isfinite(a).all():
            i = np.argwhere(~np.isfinite(a))[0].tolist()
            raise ExportError(f"{name}{i}: value is not finite [§2.3]")
    v = t["anchor.voxel"]
    if v.min(initial=0) < 0 or v.max(initial=0) > (1 << 21) - 1:
        raise ExportError("anchor.voxel: the anchors span more than 2^21 voxels on an axis; "
                          "pass a larger --voxel-size [§2.3 CoordinateOutOfRange]")
    for name in ("geometry.voxel_size", "quant.feat.step", "quant.feat.gains",
                 "quant.scaling.step", "quant.scaling.gains", "quant.offsets.step",
                 "quant.offsets.gains"):
        if (t[name] <= 0).any():
            raise ExportError(f"{name}: value not > 0 [§2.3 ValueNotPositive]")
    if "quant.feat.basis_s" in t:
        s = np.abs(t["quant.feat.basis_s"].astype(np.float64))
        if (s == 0).any():
            raise ExportError("quant.feat.basis_s: a zero (SALVQ Gain infinite) [§2.6 BasisSingular]")
        cond = s.max() / s.min()
        if cond > 1e6:
            raise ExportError(f"quant.feat.basis_s: condition number {cond:.3g} > 1e6 "
                              "(SALVQ Gain spans too wide a range) [§2.6 BasisIllConditioned]")

