"""salvq_py: an independent decoder for the SALVQ 0.10 bitstream format (spec/), in pure
Python + NumPy, written from the specification alone.

    decode(path, rate=None)            -> dict[str, np.ndarray]   the scene model (Table 2-1)
    decode_canonical(path, rate)       -> dict[str, np.ndarray]   + symbol tensors (§11.1)

Stream errors raise `SalvqError(error_class, message)` with a Table 9-1 class name.
"""
from __future__ import annotations

from .canonical import canonical_form, hashes, write_safetensors
from .container import Limits
from .decoder import Decoded, decode_bytes, decode_file
from .errors import ERROR_CLASSES, SalvqError

__all__ = ["decode", "decode_canonical", "SalvqError", "Limits", "ERROR_CLASSES",
           "decode_file", "decode_bytes", "hashes", "write_safetensors"]
__version__ = "0.10.0"


def decode(path, rate: int | None = None, limits: Limits | None = None) -> dict:
    """Decode a stream to its scene model (Table 2-1 names, in table order). `rate` defaults
    to the lowest coded rate (§7.4)."""
    return decode_file(path, rate, limits).tensors


def decode_canonical(path, rate: int | None = None, limits: Limits | None = None) -> dict:
    """The canonical decoded form (§11.1): the model plus symbols.feat/scaling/offsets (I64)."""
    return canonical_form(decode_file(path, rate, limits))
