"""The ANS decoder (§6.2), symbol/escape decoding (§6.4) and wide scales (§6.3.6, 0.14).

Faults are raised as `AnsFault(fault)`; the caller turns them into `AnsStreamInvalid`
(naming the chunk and tile) or `EscapeOverflow`.
"""
from __future__ import annotations

from .errors import SalvqError
from .tables import P, SCALE_COUNT, SCALE_INDEX_COUNT, scale_tables

_L = 1 << 32
_MASK_P = (1 << P) - 1
_HALF = 1 << (P - 1)


class AnsFault(Exception):
    """A §6.2.6 fault: Framing, ZeroTopWord, OutOfWords, WordsLeftOver, StateNotFinal."""

    def __init__(self, fault: str):
        super().__init__(fault)
        self.fault = fault


class EscapeOverflowFault(Exception):
    def __init__(self, index: int):
        super().__init__(index)
        self.index = index


class AnsDecoder:
    """§6.2.6 steps 1-3 in the constructor, §6.2.4 per interval, step 5 in `finish`."""

    __slots__ = ("words", "pos", "x", "tables")

    def __init__(self, body: bytes):
        n = len(body)
        if n % 4 != 0 or n < 8:                       # step 1
            raise AnsFault("Framing")
        words = [int.from_bytes(body[i:i + 4], "little") for i in range(0, n, 4)]
        if words[0] == 0:                             # step 2
            raise AnsFault("ZeroTopWord")
        self.x = (words[0] << 32) | words[1]          # step 3
        self.words = words
        self.pos = 2
        self.tables = scale_tables()

    def _refill(self) -> None:
        if self.x < _L:
            if self.pos >= len(self.words):
                raise AnsFault("OutOfWords")
            self.x = (self.x << 32) | self.words[self.pos]
            self.pos += 1

    def decode_binary(self, freq_one: int) -> int:
        """A binary event (§6.2.1 item 3)."""
        f1 = min(max(freq_one, 1), (1 << P) - 1)
        x = self.x
        q = x & _MASK_P
        c0 = (1 << P) - f1
        if q >= c0:
            self.x = f1 * (x >> P) + (q - c0)
            bit = 1
        else:
            self.x = c0 * (x >> P) + q
            bit = 0
        if self.x < _L:
            self._refill()
        return bit

    def decode_uniform(self, b: int) -> int:
        """A uniform value of b bits (§6.2.1 item 4, since 0.12): value v owns
        [v·2^(P−b), (v + 1)·2^(P−b)); §6.2.4 step 2 is v = floor(q / 2^(P−b))."""
        if not 1 <= b <= 12:
            raise ValueError(f"uniform value of {b} bits: §6.2.1 item 4 allows 1 … 12")
        shift = P - b
        x = self.x
        q = x & _MASK_P
        v = q >> shift
        self.x = (x >> P << shift) + (q - (v << shift))    # f·floor(x/2^P) + (q − c)
        if self.x < _L:
            self._refill()
        return v

    def decode_escape_bit(self) -> int:
        """An escape bit (§6.2.1 item 2): two halves of probability 1/2."""
        x = self.x
        q = x & _MASK_P
        if q >= _HALF:
            self.x = _HALF * (x >> P) + (q - _HALF)
            bit = 1
        else:
            self.x = _HALF * (x >> P) + q
            bit = 0
        if self.x < _L:
            self._refill()
        return bit

    def decode_symbol(self, k: int) -> int:
        """A symbol under scale index k, 0 … 127 (§6.1): k ≤ 63 by §6.4 (escapes included),
        k ≥ 64 a wide scale (§6.3.6)."""
        if k >= SCALE_COUNT:
            return self.decode_wide(k)
        t = self.tables[k]
        x = self.x
        q = x & _MASK_P
        s = t.find(q)
        c = t.cum[s]
        self.x = t.freq[s] * (x >> P) + (q - c)
        if self.x < _L:
            self._refill()
        r = t.radius
        if s != t.escape:
            return s - r
        # Exp-Golomb order 0 of w = |u| - R, then the sign.
        nzero = 0
        while True:
            b = self.decode_escape_bit()
            if b == 1:
                break
            nzero += 1
            if nzero == 31:
                raise EscapeOverflowFault(31)
        w = 1
        for _ in range(nzero):
            w = (w << 1) | self.decode_escape_bit()
        sign = self.decode_escape_bit()
        u = w + r
        return -u if sign else u

    def decode_wide(self, k: int) -> int:
        """A symbol under a wide scale k, 64 … 127 (§6.3.6, since 0.14): b = floor((k − 56) / 8)
        low bits (1 … 8), table scale t = k − 8b (56 … 63); the high part h (§6.4 at scale t,
        an escape included), then the low bits l, a uniform value of b bits (§6.2.1 item 4);
        u = h·2^b + l."""
        if not SCALE_COUNT <= k < SCALE_INDEX_COUNT:
            raise ValueError(f"scale index {k}: wide scales are 64 … 127 (§6.3.6)")
        b = (k - 56) >> 3
        h = self.decode_symbol(k - 8 * b)
        low = self.decode_uniform(b)
        return (h << b) + low

    def finish(self) -> None:
        """§6.2.6 step 5."""
        if self.pos != len(self.words):
            raise AnsFault("WordsLeftOver")
        if self.x != _L:
            raise AnsFault("StateNotFinal")


def ans_error(chunk: str, tile: int, fault: AnsFault) -> SalvqError:
    return SalvqError("AnsStreamInvalid",
                      f"chunk {chunk}, tile {tile}: {fault.fault} [§6.2.6]")
