"""Container: signature (§1.2), chunk framing and CRC-32C (§1.3), limits (§9.1)."""
from __future__ import annotations

from dataclasses import dataclass

from .errors import SalvqError

MAGIC = b"\x89SALVQ\r\n"
MAJOR = 0
MINOR = 15                  # §1.2 (0.15); §1.2.1: major 0 is the draft series, only 0.15


@dataclass
class Limits:
    """§9.1 decoder limits; the defaults are the reference defaults."""
    anchors: int = 1 << 24
    allocation_bytes: int = 1 << 32
    chunk_bytes: int = 1 << 30


def _make_crc_table() -> list[int]:
    poly = 0x82F63B78        # 0x1EDC6F41 reflected
    table = []
    for i in range(256):
        c = i
        for _ in range(8):
            c = (c >> 1) ^ poly if c & 1 else c >> 1
        table.append(c)
    return table


_CRC_TABLE = _make_crc_table()


def crc32c(data: bytes, crc: int = 0) -> int:
    """CRC-32C (Castagnoli), reflected, init and final XOR 0xFFFFFFFF (§1.3)."""
    c = crc ^ 0xFFFFFFFF
    t = _CRC_TABLE
    for b in data:
        c = t[(c ^ b) & 0xFF] ^ (c >> 8)
    return c ^ 0xFFFFFFFF


assert crc32c(b"123456789") == 0xE3069283


def check_signature(data: bytes) -> int:
    """§1.2 decoding process; returns the offset of the first chunk."""
    n = min(8, len(data))
    if data[:n] != MAGIC[:n]:
        raise SalvqError("SignatureMismatch", "the stream does not start with the SALVQ magic [§1.2]")
    if len(data) < 12:
        raise SalvqError("Truncated", "stream ends inside the signature (structure: signature) [§1.2]")
    major, minor = data[8], data[9]
    flags = int.from_bytes(data[10:12], "little")
    if major != MAJOR:
        raise SalvqError("UnsupportedMajorVersion", f"major version {major}, decoder implements {MAJOR} [§1.2]")
    if minor != MINOR:
        raise SalvqError("UnsupportedMinorVersion", f"version {major}.{minor}, decoder implements {MAJOR}.{MINOR} [§1.2]")
    if flags != 0:
        raise SalvqError("ReservedBitsSet", f"file_flags = 0x{flags:04x}: reserved bits set [§1.2]")
    return 12


def _tag_ok(tag: bytes) -> bool:
    def letter(b: int) -> bool:
        return 0x41 <= b <= 0x5A or 0x61 <= b <= 0x7A

    def digit(b: int) -> bool:
        return 0x30 <= b <= 0x39

    return letter(tag[0]) and all(letter(b) or digit(b) for b in tag[1:4])


@dataclass
class Chunk:
    tag: str
    payload: bytes
    offset: int

    @property
    def critical(self) -> bool:
        return "A" <= self.tag[0] <= "Z"


def read_chunk(data: bytes, pos: int, limits: Limits) -> tuple[Chunk, int]:
    """§1.3 steps 1-5; returns the chunk and the position after it."""
    rem = len(data) - pos
    if rem < 8:
        raise SalvqError("Truncated", "stream ends inside a chunk header (structure: chunk header) [§1.3]")
    length = int.from_bytes(data[pos:pos + 4], "little")
    tag_b = data[pos + 4:pos + 8]
    if not _tag_ok(tag_b):
        raise SalvqError("ChunkTagInvalid", f"chunk tag {tag_b!r} is not allowed [§1.3]")
    tag = tag_b.decode("ascii")
    if length > limits.chunk_bytes:
        raise SalvqError("LimitExceeded",
                         f"chunk {tag}: chunk payload length {length} above the limit {limits.chunk_bytes} [§9.1]")
    if length > rem - 8:
        raise SalvqError("ChunkLengthPastEnd",
                         f"chunk {tag}: length {length} past the end ({rem - 8} bytes left) [§1.3]")
    if rem - 8 - length < 4:
        raise SalvqError("Truncated", f"chunk {tag}: stream ends inside the chunk CRC (structure: chunk CRC) [§1.3]")
    payload = data[pos + 8:pos + 8 + length]
    stored = int.from_bytes(data[pos + 8 + length:pos + 12 + length], "little")
    computed = crc32c(payload, crc32c(tag_b))
    if stored != computed:
        raise SalvqError("ChunkCrcMismatch",
                         f"chunk {tag}: CRC-32C mismatch (stored 0x{stored:08x}, computed 0x{computed:08x}) [§1.3]")
    return Chunk(tag, payload, pos), pos + 12 + length


class Reader:
    """Bounded little-endian reader over a payload; `short` is called when it runs out."""

    __slots__ = ("buf", "pos", "on_short")

    def __init__(self, buf: bytes, pos: int = 0, on_short=None):
        self.buf = buf
        self.pos = pos
        self.on_short = on_short

    def remaining(self) -> int:
        return len(self.buf) - self.pos

    def take(self, n: int) -> bytes:
        if self.pos + n > len(self.buf):
            if self.on_short is not None:
                self.on_short()
            raise SalvqError("Truncated", "payload too short")
        b = self.buf[self.pos:self.pos + n]
        self.pos += n
        return b

    def u8(self) -> int:
        return self.take(1)[0]

    def u16(self) -> int:
        return int.from_bytes(self.take(2), "little")

    def u32(self) -> int:
        return int.from_bytes(self.take(4), "little")

    def u64(self) -> int:
        return int.from_bytes(self.take(8), "little")

    def f32_bits(self) -> int:
        return self.u32()
