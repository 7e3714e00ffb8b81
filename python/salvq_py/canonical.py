"""The canonical decoded form (§11.1; §11.6 for the explicit profile), its hashes (§11.2),
float tolerances (§11.3), and a minimal safetensors reader/writer (Annex A.1 layout)."""
from __future__ import annotations

import hashlib
import json
import struct

import numpy as np

ANCHOR_FLOAT_TENSORS = ("anchor.feat", "anchor.scaling", "anchor.offsets")
EXPLICIT_FLOAT_TENSORS = ("gaussian.position", "gaussian.log_scale", "gaussian.opacity",
                          "gaussian.rotation", "gaussian.sh_dc", "gaussian.sh_rest")   # Table 3-4
FLOAT_TENSORS = ANCHOR_FLOAT_TENSORS + EXPLICIT_FLOAT_TENSORS

_DTYPES = {"F32": "<f4", "I32": "<i4", "U8": "u1", "I8": "i1", "I64": "<i8"}
_NAMES = {np.dtype("<f4"): "F32", np.dtype("<i4"): "I32", np.dtype("u1"): "U8",
          np.dtype("i1"): "I8", np.dtype("<i8"): "I64"}


def dtype_name(a: np.ndarray) -> str:
    return _NAMES[a.dtype.newbyteorder("<") if a.dtype.byteorder == ">" else a.dtype]


def canonical_form(decoded) -> dict:
    """§11.1: Table 2-1 tensors in order, then the symbol tensors of Table 11-1; for the
    explicit profile (§11.6): Table 11-2's tensors, then Table 3-4's."""
    if decoded.profile == "explicit":
        return {**decoded.integers, **decoded.tensors}
    out = dict(decoded.tensors)
    out["symbols.feat"] = decoded.symbols["feat"].astype("<i8")
    out["symbols.scaling"] = decoded.symbols["scaling"].astype("<i8")
    out["symbols.offsets"] = decoded.symbols["offsets"].astype("<i8")
    return out


def record(name: str, a: np.ndarray) -> bytes:
    """§11.2 tensor record."""
    nb = name.encode("utf-8")
    dt = dtype_name(a).encode("ascii")
    data = np.ascontiguousarray(a).astype(a.dtype.newbyteorder("<")).tobytes()
    parts = [struct.pack("<I", len(nb)), nb, struct.pack("<I", len(dt)), dt,
             struct.pack("<I", a.ndim)] + [struct.pack("<Q", int(s)) for s in a.shape]
    parts += [struct.pack("<Q", len(data)), data]
    return b"".join(parts)


def hashes(form: dict) -> tuple[str, str]:
    """§11.2: (integer-domain hash, float hash); the float tensors in their table's order
    (§11.2 for anchors, Table 3-4 for the explicit profile, §11.6)."""
    hi = hashlib.sha256()
    for name, a in form.items():
        if name not in FLOAT_TENSORS:
            hi.update(record(name, a))
    hf = hashlib.sha256()
    for name in FLOAT_TENSORS:
        if name in form:
            hf.update(record(name, form[name]))
    return hi.hexdigest(), hf.hexdigest()


def write_safetensors(path: str, tensors: dict, metadata: dict | None = None) -> None:
    header = {}
    if metadata:
        header["__metadata__"] = metadata
    blobs = []
    off = 0
    for name, a in tensors.items():
        data = np.ascontiguousarray(a).astype(a.dtype.newbyteorder("<")).tobytes()
        header[name] = {"dtype": dtype_name(a), "shape": [int(s) for s in a.shape],
                        "data_offsets": [off, off + len(data)]}
        blobs.append(data)
        off += len(data)
    hj = json.dumps(header, separators=(",", ":")).encode("utf-8")
    hj += b" " * ((-len(hj)) % 8)
    with open(path, "wb") as fh:
        fh.write(struct.pack("<Q", len(hj)))
        fh.write(hj)
        for b in blobs:
            fh.write(b)


def read_safetensors(path: str) -> dict:
    with open(path, "rb") as fh:
        buf = fh.read()
    n = struct.unpack("<Q", buf[:8])[0]
    header = json.loads(buf[8:8 + n])
    base = 8 + n
    out = {}
    for name, info in header.items():
        if name == "__metadata__":
            continue
        b, e = info["data_offsets"]
        a = np.frombuffer(buf[base + b:base + e], _DTYPES[info["dtype"]]).reshape(info["shape"])
        out[name] = a
    return out


def float_match(a: np.ndarray, b: np.ndarray, rel: float, abs_: float) -> np.ndarray:
    """§11.3 per element."""
    a64 = a.astype(np.float64)
    b64 = b.astype(np.float64)
    both_nan = np.isnan(a64) & np.isnan(b64)
    same_inf = np.isinf(a64) & np.isinf(b64) & (a64 == b64)
    fin = np.isfinite(a64) & np.isfinite(b64)
    with np.errstate(invalid="ignore"):
        close = fin & (np.abs(a64 - b64) <= rel * np.abs(b64) + abs_)
    return both_nan | same_inf | close
