"""salvq_py: an independent decoder for the SALVQ 0.15 bitstream format (spec/), both
profiles (the explicit profile's progressive streams, §3.8, included), in pure Python + NumPy,
written from the specification alone.

    decode(path, rate=None)            -> dict[str, np.ndarray]   the scene model (Table 2-1),
                                                                  or the Gaussians (Table 3-4)
    decode_canonical(path, rate)       -> dict[str, np.ndarray]   the canonical form (§11.1,
                                                                  §11.6 for the explicit profile)
    decode_canonical(path, rate, region=(x0, y0, z0, x1, y1, z1))
                                       -> the canonical form of a region decode (§10.3.1, §11.7)

Stream errors raise `SalvqError(error_class, message)` with a Table 9-1 class name.
"""
from __future__ import annotations

from .canonical import canonical_form, hashes, write_safetensors
from .container import Limits
from .decoder import Decoded, ExplicitDecoded, decode_bytes, decode_file
from .errors import ERROR_CLASSES, SalvqError
from .region import RegionError, parse_region

__all__ = ["decode", "decode_canonical", "SalvqError", "Limits", "ERROR_CLASSES",
           "decode_file", "decode_bytes", "Decoded", "ExplicitDecoded", "hashes",
           "write_safetensors", "RegionError", "parse_region"]
__version__ = "0.15.0"


def decode(path, rate: int | None = None, limits: Limits | None = None, region=None,
           prefix: bool = False) -> dict:
    """Decode a stream to its scene model (Table 2-1 names, in table order) or, for the
    explicit profile, its Gaussians (Table 3-4). `rate` defaults to the lowest coded rate.
    `region` (six numbers, min x, y, z, max x, y, z, or that as a comma-separated string)
    decodes only the tiles the box meets (§10.3.1); a bad box raises RegionError. `prefix`
    consents to decoding a progressive stream that ends early to its last complete layer
    (§3.8.4; `decode_file` tells which rate was decoded)."""
    return decode_file(path, rate, limits, region, prefix).tensors


def decode_canonical(path, rate: int | None = None, limits: Limits | None = None,
                     region=None, prefix: bool = False) -> dict:
    """The canonical decoded form: the model plus symbols.feat/scaling/offsets (I64, §11.1),
    or Table 11-2 then Table 3-4 for the explicit profile (§11.6); of a region decode
    (§11.7) when `region` is given."""
    return canonical_form(decode_file(path, rate, limits, region, prefix))
