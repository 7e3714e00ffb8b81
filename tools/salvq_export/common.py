"""Constants of the public HAC code and the spec that several modules use, and ExportError."""
from __future__ import annotations

SCHEMA = "0.2"
# HAC's fixed base steps: HAC:scene/gaussian_model.py:conduct_encoding (Q_feat = 1,
# Q_scaling = 0.001, Q_offsets = 0.2; same in gaussian_renderer/__init__.py).
HAC_Q_FEAT, HAC_Q_SCALING, HAC_Q_OFFSETS = 1.0, 0.001, 0.2
# HAC:utils/encodings.py: anchor_round_digits = 16, Q_anchor = 1 / (2^16 - 1).
ANCHOR_ROUND_DIGITS = 16
# HAC:submodules/gridencoder/src/gridencoder.cu:fast_hash (the same primes as spec §2.4).
PRIME_1, PRIME_2 = 2654435761, 805459861
# spec §5.1: W = 10 weight bits.
W_BITS = 10


class ExportError(Exception):
    """A checkpoint that cannot be mapped; the message names the A.7 rule."""
