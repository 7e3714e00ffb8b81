"""Conformance of salvq_py against conformance/vectors (spec §11), without the Rust binary.

Run with `python3 -m pytest python/tests` if pytest is installed, or directly:
`python3 python/tests/test_conformance.py`.

* valid vectors: every listed rate is decoded; the integer-domain hash (§11.2) must equal the
  manifest's; every tensor in the expected file must match (integer domain byte for byte,
  float tensors within the §11.3 tolerance); the float hash is reported (bit-exact or not).
* must-fail vectors: decoding must raise SalvqError with the manifest's error class.
* region decodes (§10.3.1, §11.7): every `decodes` entry with a `region` member, of valid and
  must-fail vectors, is decoded with its box and checked as above; plus `test_region_decodes`
  (boxes that are no box refused before the stream is read, CLI exit status 2; an unbounded
  box gives the full decode; the re-basing of spatial regions, §10.3.1 step 5).
* progressive streams (§3.8, 0.15): both vectors' GRSY re-encoded byte for byte, edited
  progressive streams with the reference's outcome (`progressive_cases`), §3.7's extraction,
  §3.8.4's prefix decodes with and without consent, and region decodes of a progressive stream.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))

import numpy as np  # noqa: E402

from salvq_py import RegionError, SalvqError, decode_bytes, decode_file  # noqa: E402
from salvq_py.ans import AnsDecoder  # noqa: E402
from salvq_py.canonical import (FLOAT_TENSORS, canonical_form, float_match, hashes,  # noqa: E402
                                read_safetensors)
from salvq_py.container import crc32c  # noqa: E402
from salvq_py.region import rebase  # noqa: E402
from salvq_py.tables import check_step_factor, scale_tables  # noqa: E402

VECTORS = os.environ.get("SALVQ_VECTORS",
                         os.path.join(HERE, "..", "..", "conformance", "vectors"))


def _manifest():
    with open(os.path.join(VECTORS, "manifest.json")) as fh:
        return json.load(fh)["vectors"]


def _read(name):
    with open(os.path.join(VECTORS, name), "rb") as fh:
        return fh.read()


def check_valid(vec, regions_only: bool = False) -> list[str]:
    """Returns a list of notes; raises AssertionError on a failure. Region decodes (§11.7)
    are decoded with their box; `regions_only` checks only those (must-fail vectors)."""
    notes = []
    data = _read(vec["file"])
    k = 0
    for dec in vec["decodes"]:
        rate = dec["rate"]
        region = dec.get("region")
        if region is None and regions_only:
            continue
        if region is not None:
            decoded = decode_bytes(data, rate, region=region["box"])
            assert decoded.tiles == region["tiles"], \
                f"{vec['name']}@{rate} region {k}: tiles {decoded.tiles}, expected {region['tiles']}"
            rate = f"{rate} region {k}"
            k += 1
        else:
            decoded = decode_bytes(data, rate)
        form = canonical_form(decoded)
        ih, fh = hashes(form)
        assert ih == dec["integer_sha256"], f"{vec['name']}@{rate}: integer-domain hash differs"
        expected = read_safetensors(os.path.join(VECTORS, dec["expected"]))
        omitted = set(dec.get("omitted") or [])
        assert set(expected) | omitted == set(form), f"{vec['name']}@{rate}: tensor set differs"
        tol = dec["tolerance"]
        for name, exp in expected.items():
            got = form[name]
            assert got.dtype.str[1:] == exp.dtype.str[1:] and got.shape == exp.shape, \
                f"{vec['name']}@{rate}: {name} dtype/shape"
            if name in FLOAT_TENSORS:
                ok = float_match(got, exp, tol["relative"], tol["absolute"])
                if not ok.all():
                    i = int(np.argmin(ok.ravel()))
                    raise AssertionError(f"{vec['name']}@{rate}: {name}[{i}] outside tolerance")
            else:
                assert got.tobytes() == exp.tobytes(), f"{vec['name']}@{rate}: {name} differs"
        notes.append(f"@{rate} " + ("bit-exact" if fh == dec["float_sha256"] else "within tolerance"))
    return notes


def check_must_fail(vec) -> str:
    try:
        decode_bytes(_read(vec["file"]), vec["rate"])
    except SalvqError as e:
        assert e.error_class == vec["error_class"], \
            f"{vec['name']}: got {e.error_class} ({e.message}), expected {vec['error_class']}"
        notes = check_valid(vec, regions_only=True) if vec.get("decodes") else []
        return ", ".join([e.error_class] + notes)
    raise AssertionError(f"{vec['name']}: decoded, expected {vec['error_class']}")


def test_region_decodes():
    """§10.3.1 beyond the vectors: a box with a NaN or min > max is refused before the stream
    is read (RegionError; the CLI exits 2, not 1), an unbounded box (and one that only touches
    every tile) selects every tile and gives the full decode's canonical form, and step 5's
    re-basing on hand-made runs."""
    for bad in ("nan,0,0,1,1,1", "0,0,0,1,nan,1", "0,0,2,1,1,1", "1,0,0,0,1,1", "1,2,3",
                "0,0,0,1,1,x"):
        try:
            decode_file("/nonexistent/stream.salvq", 0, region=bad)
        except RegionError:
            pass
        else:
            raise AssertionError(f"box {bad!r} accepted")
        r = subprocess.run([sys.executable, "-m", "salvq_py", os.path.join(VECTORS, "g-sh0.salvq"),
                            os.path.join(tempfile.gettempdir(), "salvq_py-region-test.st"), "0", bad],
                           cwd=os.path.dirname(HERE), capture_output=True, text=True)
        assert r.returncode == 2 and "no box" in r.stderr, (bad, r.returncode, r.stderr)
    everything = "-inf,-inf,-inf,inf,inf,inf"
    for name, rate in (("tiles-regions", 0), ("sp-salvq-regions", 1), ("g-sh0", 0),
                       ("g-sh3-rates", 2), ("g-sh3-progressive", 1), ("g-sh0-progressive-skip", 0)):
        data = _read(f"{name}.salvq")
        whole = decode_bytes(data, rate)
        part = decode_bytes(data, rate, region=everything)
        assert hashes(canonical_form(part)) == hashes(canonical_form(whole)), name
        # a degenerate box on -0.0 = +0.0 is a box (min ≤ max)
        decode_bytes(data, rate, region="0,0,0,-0.0,0,0")
    # step 5: starts 4, 9 (regions [0,4), [4,9), [9,N)); selected rows 5..12
    rows = np.arange(5, 13)
    assert rebase([4, 9], rows) == ([1, 2], [0, 4])           # region 0 drops out
    assert rebase([4, 9], np.arange(0, 3)) == ([0], [0])       # only region 0 left
    assert rebase([4, 9], np.array([0, 1, 10])) == ([0, 2], [0, 2])   # region 1 empty
    assert rebase([4, 9], np.zeros(0, np.int64)) == ([0], [0])  # N' = 0: region 0 alone


# ----------------------------------------------------------------- pytest entry points

def test_crc32c_check_value():
    assert crc32c(b"123456789") == 0xE3069283          # §1.3


def test_tables_match_data_files():
    check_step_factor()                                # Table 5-2 SHA-256 (§5.4)
    scale_tables(verify=True)                          # §6.3.5 SHA-256


def test_ans_golden_vector():                          # §6.2.8
    words = [0x3220F91D, 0xF52C9853, 0x94600DFE, 0xC9DFB75B, 0x5E000000]
    d = AnsDecoder(b"".join(w.to_bytes(4, "little") for w in words))
    got = [d.decode_symbol(24), d.decode_symbol(24), d.decode_symbol(40), d.decode_binary(1 << 14),
           d.decode_symbol(0), d.decode_symbol(0), d.decode_symbol(10), d.decode_binary(60000),
           d.decode_symbol(63), d.decode_symbol(63)]
    assert got == [0, -3, 5, 1, 0, 1, -100, 0, 17, -1000000]
    d.finish()


def _uniform_or_binary(rng, kind):
    """A random uniform value of 1 … 12 bits (kind 0) or binary event (kind 1)."""
    if kind == 0:
        b = rng.randrange(1, 13)
        return ("u", b, rng.randrange(1 << b))
    f = rng.choice((1, 2, 1 << 15, 65535, rng.randrange(1, 1 << 16)))
    return ("b", f, int(rng.random() < f / 65536))


def _random_round_trips(seed, kinds, most, symbol):
    """40 random event lists of up to `most` events, each event's kind drawn from 0 … kinds − 1:
    a uniform value or a binary event for 0 and 1, symbol(rng, kind) for the others."""
    import random
    rng = random.Random(seed)
    for trial in range(40):
        events = []
        for _ in range(rng.randrange(0, most)):
            kind = rng.randrange(kinds)
            events.append(_uniform_or_binary(rng, kind) if kind < 2 else symbol(rng, kind))
        _ans_round_trip(events, trial)


def _ans_round_trip(events, trial):
    """Encodes events ("u", bits, value), ("b", freq_one, bit) and ("s", k, u) by §6.2.3
    (tools/reencode.py) and checks that they decode back."""
    sys.path.insert(0, os.path.join(HERE, "..", "tools"))
    from reencode import binary_interval, encode_body, symbol_intervals, uniform_interval
    intervals = []
    for kind, p, v in events:
        if kind == "u":
            intervals.append(uniform_interval(v, p))
        elif kind == "b":
            intervals.append(binary_interval(v, p))
        else:
            intervals += symbol_intervals(v, p)
    d = AnsDecoder(encode_body(intervals))
    for kind, p, v in events:
        got = (d.decode_uniform(p) if kind == "u" else
               d.decode_binary(p) if kind == "b" else d.decode_symbol(p))
        assert got == v, f"trial {trial}: {kind} {p}: {got} != {v}"
    d.finish()


def test_ans_uniform_values():                         # §6.2.1 item 4 (0.12)
    """Uniform values of 1 … 12 bits between binary events and symbols, encoded by §6.2.3
    (tools/reencode.py) and decoded back; no vector has b other than 3 (§8.2's octants)."""
    _random_round_trips(12, 3, 400, lambda rng, kind: (
        "s", rng.randrange(64), rng.randrange(-200, 201)))


def test_ans_wide_scales():                            # §6.3.6 (0.14)
    """Symbols at wide scales 64 … 127 among table symbols, binary events and uniform values,
    encoded by tools/reencode.py (high part h = floor(u / 2^b) at t = k − 8b, then b low
    bits) and decoded back: every number of low bits 1 … 8, negative u (h rounded toward −∞),
    and h beyond the table's radius (an escape inside a wide scale, which g-wide-scales does
    not have)."""
    sys.path.insert(0, os.path.join(HERE, "..", "tools"))
    from reencode import encode_body, symbol_intervals, uniform_interval
    from salvq_py.tables import scale_tables
    # u = −1 at k = 64 (b = 1, t = 56): h = −1, low bit 1
    assert symbol_intervals(-1, 64) == symbol_intervals(-1, 56) + [uniform_interval(1, 1)]
    # u = 2^31 + 2^8 at k = 127 (b = 8, t = 63): h = 2^23 + 1, escaped (R_63 = 127), w = h − 127
    # has L = 22: ESCAPE, 22 + 1 prefix bits, 22 suffix bits, the sign, then the 8 low bits
    assert len(symbol_intervals((1 << 31) + 256, 127)) == 1 + 23 + 22 + 1 + 1
    def wide_symbol(rng, kind):
        k = rng.randrange(64, 128) if kind == 2 else rng.randrange(128)
        b = max((k - 56) >> 3, 0)
        spread = rng.choice((2, 200 << b, 1 << (24 + b // 2), 1 << 30))
        return ("s", k, rng.choice((-1, 0, rng.randrange(-spread, spread + 1))))
    _random_round_trips(14, 4, 300, wide_symbol)
    # a wide scale's h escaped past 30 prefix zeros is EscapeOverflow, as at its table scale
    from salvq_py.ans import EscapeOverflowFault
    t = scale_tables()[63]
    body = encode_body([(t.cum[t.escape], t.freq[t.escape])] + [(0, 1 << 15)] * 31)
    try:
        AnsDecoder(body).decode_symbol(127)
    except EscapeOverflowFault:
        pass
    else:
        raise AssertionError("31 zero prefix bits in a wide scale's high part not refused")


def _mlps_edit(data: bytes, body_fn) -> bytes:
    """Replace the MLPS payload by body_fn(payload), CRC recomputed (§1.3)."""
    pos = 12
    while pos + 8 <= len(data):
        n = int.from_bytes(data[pos:pos + 4], "little")
        tag = data[pos + 4:pos + 8]
        if tag == b"MLPS":
            p = body_fn(data[pos + 8:pos + 8 + n])
            crc = crc32c(p, crc32c(tag)).to_bytes(4, "little")
            return (data[:pos] + len(p).to_bytes(4, "little") + tag + p + crc
                    + data[pos + 12 + n:])
        pos += 12 + n
    raise KeyError("MLPS")


def _mlps_parts(p: bytes, d):
    """Split an MLPS payload (coding_method included) into its §1.6.2 fields."""
    from salvq_py.hyperprior import CONTEXT_PRECISION, mlps_context_length
    w, wdtype = CONTEXT_PRECISION[p[1]]
    H, Cin, Cout = d.H, d.Cin, d.Cout
    pos = 2 + 2 + Cout                                  # method, precision, a0, shift0, a1
    head = p[2:pos]
    w0 = np.frombuffer(p, wdtype, H * Cin, pos); pos += w * H * Cin          # noqa: E702
    b0 = p[pos:pos + 4 * H]; pos += 4 * H                                     # noqa: E702
    w1 = np.frombuffer(p, wdtype, Cout * H, pos); pos += w * Cout * H        # noqa: E702
    b1 = p[pos:pos + 4 * Cout]; pos += 4 * Cout                               # noqa: E702
    assert pos == 1 + mlps_context_length(d, w)
    return head, w0, b0, w1, b1, p[pos:]


def _mlps_join(p0: bytes, cprec: int, head, w0, b0, w1, b1, rest) -> bytes:
    dt = "<i2" if cprec == 0 else "i1"
    return (p0[:1] + bytes([cprec]) + head + np.asarray(w0).astype(dt).tobytes() + b0
            + np.asarray(w1).astype(dt).tobytes() + b1 + rest)


def test_mlps_precision_checks():
    """§1.6.2 (0.10): the checks on context_precision and scaffold_precision and their order
    (steps 1-7), on edited streams; i8 weights sign-extend to the same §5.3 integers
    (Table 1-7); binary16 values widen exactly to binary32 (Table 1-6)."""
    from salvq_py.hyperprior import mlps_context_length, scaffold_specs, scaffold_value_count
    vec = next(v for v in _manifest() if v["kind"] == "valid")
    data, rate = _read(vec["file"]), vec["decodes"][0]["rate"]
    base = decode_bytes(data, rate)
    n = scaffold_value_count(base.dims)
    full = 1 + mlps_context_length(base.dims, 2) + 1 + 4 * n     # step 1's reported length

    def cls(fn, dat=data):
        try:
            decode_bytes(_mlps_edit(dat, fn), rate)
            return "ok"
        except SalvqError as e:
            return e.error_class

    def msg(fn):
        try:
            decode_bytes(_mlps_edit(data, fn), rate)
        except SalvqError as e:
            return e.message
        return ""

    # Run the scaffold_precision cases on both context precisions (i8 and i16 weights).
    streams = {}
    for cprec in (0, 1):
        streams[cprec] = _mlps_edit(data, lambda p, c=cprec: _mlps_join(p, c, *_mlps_parts(p, base.dims)))
    for cprec, dat in streams.items():
        w = 2 if cprec == 0 else 1
        c = 1 + mlps_context_length(base.dims, w)      # payload bytes before scaffold_precision

        def values(p, c=c):
            return np.frombuffer(p[c + 1:], "<f4" if p[c] == 0 else "<f2")

        h = lambda p, values=values: np.clip(values(p), -65504, 65504).astype("<f2")  # noqa: E731
        f = lambda p, values=values: values(p).astype("<f4")                          # noqa: E731
        bad_a0 = lambda p, c=c: p[:2] + bytes([31]) + p[3:c]                          # noqa: E731
        cases = [
            (lambda p: p[:1], "ChunkSizeMismatch"),                                    # step 1
            (lambda p, c=c: p[:c], "ChunkSizeMismatch"),                               # step 3
            (lambda p: p[:1] + b"\x02", "FieldOutOfRange"),                            # 2 before 3
            (lambda p, c=c: p[:1] + b"\xff" + p[2:c], "FieldOutOfRange"),
            (lambda p, c=c: p[:1] + b"\x02" + p[2:c] + b"\x01" + h(p).tobytes(), "FieldOutOfRange"),
            (lambda p, c=c: p[:1] + b"\x02" + bad_a0(p)[2:] + b"\x05", "FieldOutOfRange"),
            (lambda p, c=c: p[:c] + b"\x02" + h(p).tobytes(), "FieldOutOfRange"),      # step 4
            (lambda p, c=c: p[:c] + b"\xff", "FieldOutOfRange"),                       # 4 before 5
            (lambda p, c=c: p[:c] + b"\x01" + f(p).tobytes(), "ChunkSizeMismatch"),    # step 5
            (lambda p, c=c: p[:c] + b"\x00" + h(p).tobytes(), "ChunkSizeMismatch"),
            (lambda p, c=c: bad_a0(p) + b"\x02" + h(p).tobytes(), "FieldOutOfRange"),
            (lambda p, c=c: bad_a0(p) + b"\x01" + h(p).tobytes() + b"\0", "ChunkSizeMismatch"),  # 5 before 6
            (lambda p, c=c: bad_a0(p) + b"\x01" + h(p).tobytes(), "FieldOutOfRange"),  # step 6
            (lambda p, c=c: p[:c] + b"\x01" + np.r_[h(p)[:-1], np.float16(np.nan)].astype("<f2").tobytes(),
             "NonFiniteValue"),                                                         # step 7
            (lambda p, c=c: p[:c] + b"\x01" + np.r_[np.float16(-np.inf), h(p)[1:]].astype("<f2").tobytes(),
             "NonFiniteValue"),
            (lambda p, c=c: bad_a0(p) + b"\x01" + np.r_[np.float16(np.nan), h(p)[1:]].astype("<f2").tobytes(),
             "FieldOutOfRange"),                                                        # 6 before 7
        ]
        for i, (fn, want) in enumerate(cases):
            got = cls(fn, dat)
            assert got == want, f"MLPS (context_precision {cprec}) case {i}: {got}, expected {want}"

        # i8 and i16 storage of the same integers decode identically (Table 1-7).
        dec = decode_bytes(dat, rate)
        assert all(dec.tensors[k].tobytes() == base.tensors[k].tobytes() for k in base.tensors)
        assert all(dec.symbols[k].tobytes() == base.symbols[k].tobytes() for k in base.symbols)

        special = np.array([2.0 ** -24, -0.0, 65504.0, -(2.0 ** -15)], "<f2")
        edited = _mlps_edit(dat, lambda p, c=c, h=h: p[:c] + b"\x01"
                            + np.r_[special, h(p)[4:]].astype("<f2").tobytes())
        dec = decode_bytes(edited, rate)
        name, shape = scaffold_specs(base.dims)[0]
        got = dec.tensors[name].ravel()[:4]
        assert got.dtype == np.float32 and got.tobytes() == special.astype("<f4").tobytes()
        assert all(dec.symbols[k].tobytes() == base.symbols[k].tobytes() for k in base.symbols)

    # Reported lengths are payload lengths: step 1 as for i16 and binary32 (context(2)).
    assert f"expected {full}" in msg(lambda p: p[:1])
    assert "context_precision" in msg(lambda p: p[:1] + b"\x02")
    # i8 sign extension (Table 1-7): bytes 0x80 and 0x7F are the integers -128 and 127.
    from salvq_py.hyperprior import parse_mlps
    i = data.index(b"MLPS") - 4
    payload = data[i + 8:i + 8 + int.from_bytes(data[i:i + 4], "little")]
    assert payload[1] == 1, "the first valid vector stores its context weights as i8"
    head, w0, b0, w1, b1, rest = _mlps_parts(payload, base.dims)
    w0, w1 = w0.copy(), w1.copy()
    w0[0], w0[-1], w1[0], w1[-1] = -128, 127, -1, -128
    mlp, _ = parse_mlps(_mlps_join(payload, 1, head, w0, b0, w1, b1, rest), base.dims)
    assert (mlp.w0.ravel()[[0, -1]].tolist(), mlp.w1.ravel()[[0, -1]].tolist()) == ([-128, 127], [-1, -128])
    mlp16, _ = parse_mlps(_mlps_join(payload, 0, head, w0, b0, w1, b1, rest), base.dims)
    assert mlp16.w0.tobytes() == mlp.w0.tobytes() and mlp16.w1.tobytes() == mlp.w1.tobytes()
    assert n == sum(int(np.prod(s)) for _, s in scaffold_specs(base.dims))


def _chunk_edit(data: bytes, tag: str, fn, nth: int = 0) -> bytes:
    """Replace the nth `tag` chunk's payload by fn(bytearray(payload)) when that returns bytes,
    else by the bytearray fn edited in place; CRC recomputed (§1.3)."""
    pos, k = 12, 0
    while pos + 8 <= len(data):
        n = int.from_bytes(data[pos:pos + 4], "little")
        t = data[pos + 4:pos + 8]
        if t == tag.encode():
            if k == nth:
                p = bytearray(data[pos + 8:pos + 8 + n])
                q = fn(p)
                p = bytes(q if isinstance(q, (bytes, bytearray)) else p)
                crc = crc32c(p, crc32c(t)).to_bytes(4, "little")
                return data[:pos] + len(p).to_bytes(4, "little") + t + p + crc + data[pos + 12 + n:]
            k += 1
        pos += 12 + n
    raise KeyError(tag)


def _chunk_insert(data: bytes, after: str, tag: str, payload: bytes) -> bytes:
    pos = 12
    while True:
        n = int.from_bytes(data[pos:pos + 4], "little")
        end = pos + 12 + n
        if data[pos + 4:pos + 8] == after.encode():
            crc = crc32c(payload, crc32c(tag.encode())).to_bytes(4, "little")
            return data[:end] + len(payload).to_bytes(4, "little") + tag.encode() + payload + crc + data[end:]
        pos = end


def explicit_cases() -> list[tuple[str, bytes, int, str]]:
    """Edited explicit-profile streams (§3) that no vector covers, as (label, stream, rate,
    expected): a class, "ok", or "ok:<integer-domain hash>:<float hash>". Each expectation is
    the reference decoder's (that wrote the 0.11 vectors), which salvq_py matched; they
    still hold on the 0.12 vectors (0.12 changed only the octree's events, §8.2) and on 0.13's
    (0.13 changed only layers with an sh_rest group, §3.4, §3.5; the cases re-encode g-sh0,
    which has none, and edit only the first byte of g-sh3-rates' payloads) and on 0.14's (0.14
    changed only the explicit profile's scale indices above 63, §3.4, §3.5, §6.3.6: g-sh0's
    layer now codes 2 symbols at wide scale 64 and the re-encoded cases code theirs by
    §6.3.6 too, so the decoded values, hence the expected hashes, are unchanged), and
    `tools/probe_reference.py` reruns them on both. The float hashes were taken again from the
    reference when §3.6 step 3 moved to binary64 (0.15), which salvq_py matched."""
    import struct
    sys.path.insert(0, os.path.join(HERE, "..", "tools"))
    from reencode import encode_gatt
    from salvq_py.explicit import parse_glay
    from salvq_py.tiles import parse_tils
    s0, s3 = _read("g-sh0.salvq"), _read("g-sh3-rates.salvq")
    f32 = lambda x: struct.pack("<f", x)                                        # noqa: E731

    def assign(p, at, b):
        p[at:at + len(b)] = b

    def glay(fn):          # GLAY: method, coord_bits, voxel_size@2, pred_level@6,
        return _chunk_edit(s0, "GLAY", fn)   # rotation_freq@7, size_threshold@13, refine@25

    def gqua(fn):          # g-sh3-rates (M = 3): group 0 at byte 1: lattice, step, gains[3], mean[3]
        return _chunk_edit(s3, "GQUA", fn)

    sh_dc = 1 + (1 + 4 + 12 + 12) + (1 + 4 + 12 + 4) + (1 + 4 + 12 + 12)   # group 3 (lattice 4)
    bu, bs = sh_dc + 1 + 4 + 12 + 12, sh_dc + 1 + 4 + 12 + 12 + 18         # its basis_u, basis_s
    zero_top = lambda p: assign(p, 1 + 4 * 3, bytes(4))     # tile 0's GATT body   # noqa: E731
    cases = [
        ("GLAY voxel_size NaN, pred_level 200 (stream order)",
         glay(lambda p: (assign(p, 2, f32(float("nan"))), assign(p, 6, b"\xc8"))), 0, "NonFiniteValue"),
        ("GLAY voxel_size 0, rotation_freq[0] = 0",
         glay(lambda p: (assign(p, 2, f32(0.0)), assign(p, 7, b"\0\0"))), 0, "ValueNotPositive"),
        ("GLAY size_threshold[1] < size_threshold[0], refine[0] = 30",
         glay(lambda p: (assign(p, 13, struct.pack("<i", 100)), assign(p, 25, b"\x1e"))), 0, "ValueInvalid"),
        ("GQUA lattice 7, payload ends after it (checked as read)",
         gqua(lambda p: (assign(p, 1, b"\x07"), p[:2])[1]), 0, "ValueInvalid"),
        ("GQUA gains[0, 0] = 0, payload ends after gains[0, 1]",
         gqua(lambda p: (assign(p, 6, f32(0.0)), p[:14])[1]), 0, "ValueNotPositive"),
        ("GQUA mean[0, 0] NaN, payload ends after mean[0, 1]",
         gqua(lambda p: (assign(p, 18, f32(float("nan"))), p[:26])[1]), 0, "NonFiniteValue"),
        ("GQUA basis_u[3, 0] NaN, payload ends inside basis_u",
         gqua(lambda p: (assign(p, bu, b"\x00\x7e"), p[:bu + 4])[1]), 0, "NonFiniteValue"),
        ("GQUA step ⊗ gain[0, 1] overflows, gains[0, 2] = 0 (every gain before the products)",
         gqua(lambda p: (assign(p, 2, f32(3e38)), assign(p, 10, f32(2.0)), assign(p, 14, f32(0.0)))),
         0, "ValueNotPositive"),
        ("GQUA basis_s[3, 0] = −0, basis_s[3, 2] = inf",
         gqua(lambda p: (assign(p, bs, b"\x00\x80"), assign(p, bs + 4, b"\x00\x7c"))), 0, "NonFiniteValue"),
        ("GQUA basis_s[3, 0] = −0", gqua(lambda p: assign(p, bs, b"\x00\x80")), 0, "BasisSingular"),
        ("GQUA basis_s[3, 0] = 2^−24", gqua(lambda p: assign(p, bs, b"\x01\x00")), 0, "ok"),
        ("layer 0's GLAY coding_method 5, rate 2 (not parsed)",
         _chunk_edit(s3, "GLAY", lambda p: assign(p, 0, b"\x05"), 0), 2, "ok"),
        ("layer 2's GLAY coding_method 5, rate 0",
         _chunk_edit(s3, "GLAY", lambda p: assign(p, 0, b"\x05"), 2), 0, "ok"),
        ("layer 1's GATT empty, rate 0", _chunk_edit(s3, "GATT", lambda p: bytearray(), 1), 0, "ok"),
        ("selected GATT broken, a byte after SEND (decoded as read)",
         _chunk_edit(s3, "GATT", zero_top, 0) + b"\0", 0, "AnsStreamInvalid"),
        ("selected GATT broken, the next layer's GLAY broken",
         _chunk_edit(_chunk_edit(s3, "GATT", zero_top, 0), "GLAY", lambda p: assign(p, 0, b"\x05"), 1),
         0, "AnsStreamInvalid"),
        ("selected GATT empty", _chunk_edit(s0, "GATT", lambda p: bytearray()), 0, "ChunkSizeMismatch"),
        ("selected GLAY coding_method 1", _chunk_edit(s0, "GLAY", lambda p: assign(p, 0, b"\x01")), 0,
         "UnknownCodingMethod"),
        ("HEAD after GQUA", _chunk_insert(s0, "GQUA", "HEAD", bytes(61)), 0, "UnknownCriticalChunk"),
        ("GHED after GQUA", _chunk_insert(s0, "GQUA", "GHED", bytes(35)), 0, "ChunkOrder"),
        ("GHED after HEAD (anchors profile)",
         _chunk_insert(_read("usq-one-rate.salvq"), "HEAD", "GHED", bytes(35)), 1, "UnknownCriticalChunk"),
        ("GQUA first", s0[:12] + s0[12 + 12 + 35:], 0, "UnknownCriticalChunk"),
    ]

    # §3.5: g-sh0's layer re-encoded with predict[scale] = 1 (the size class comes from the
    # coordinates u, not the symbols r: the decode must not change), then with |u| = 2^24
    # (allowed) and 2^24 + 1 (ValueInvalid).
    base = decode_bytes(s0, 0)
    h, ints = base.head, base.integers
    tils = parse_tils(_payload(s0, "TILS"), h.N, parse_glay(_payload(s0, "GLAY"), h).coord_bits)

    def reencode(glay_fn, coords):
        data = _chunk_edit(s0, "GLAY", glay_fn)
        lay = parse_glay(_payload(data, "GLAY"), h)
        gatt = encode_gatt(h, lay, tils, ints["gaussian.voxel"], coords, ints["symbols.rotation_index"],
                           ints["symbols.size_class"], ints["symbols.refinement"])
        return _chunk_edit(data, "GATT", lambda p: gatt)

    predict0 = 1 + 28 + 8 * (h.G - 1)                 # GLAY: predict after shift, scale_offset
    cases.append(("GLAY predict[scale] = 1, layer re-encoded (same decode as g-sh0)",
                  reencode(lambda p: assign(p, predict0, b"\x01"), ints["symbols.coordinates"]), 0, "ok"))
    for value, want in ((1 << 24, "ok"), (-(1 << 24), "ok"), ((1 << 24) + 1, "ValueInvalid")):
        coords = ints["symbols.coordinates"].copy()
        coords[60, 3] = value                     # the opacity of tile 1's ninth Gaussian
        cases.append((f"GATT opacity u = {value}, re-encoded", reencode(lambda p: None, coords), 0, want))

    # Valid edge cases of §3.5 and §3.6, with the reference decoder's hashes (§11.2):
    # "ok:<integer-domain hash>:<float hash>" (g-sh0's D = 10: scale 0-2, opacity 3,
    # rotation 4-6, sh_dc 7-9; sh_dc is predicted, so the rescale clamp is reached).
    def coords_with(fn):
        c = ints["symbols.coordinates"].copy()
        fn(c)
        return c

    def rot_index(k):
        data = _chunk_edit(s0, "GLAY", lambda p: None)
        lay = parse_glay(_payload(data, "GLAY"), h)
        gatt = encode_gatt(h, lay, tils, ints["gaussian.voxel"], ints["symbols.coordinates"],
                           np.full(h.N, k, np.uint8), ints["symbols.size_class"], ints["symbols.refinement"])
        return _chunk_edit(data, "GATT", lambda p: gatt)

    same_ints = "dbd4a52fe78c627903697f3000665a2ab33472f610cc82d70213b3b65df7deb7"
    rotation_step = 1 + (1 + 4 + 4 + 12) + (1 + 4 + 4 + 4) + 1      # GQUA: group 2's step
    huge_voxel = lambda p: assign(p, 2, f32(3e38))                  # noqa: E731
    cases += [
        ("sh_dc u = 2^24 everywhere (rescale clamps to ±2^24)",
         reencode(lambda p: None, coords_with(lambda c: c.__setitem__((slice(None), slice(7, 10)), 1 << 24))), 0,
         "ok:56dbb814a7897815cd8d066850a77e4f951faef744ef4c75d654a02a03e2b8af"
         ":ebd1abdd6ab99c5ab539e91e51203aeca34ae13c0cf56d9cf4f4c61b65c843f7"),
        ("sh_dc u = −2^24 + 1 everywhere",
         reencode(lambda p: None, coords_with(lambda c: c.__setitem__((slice(None), slice(7, 10)), 1 - (1 << 24)))),
         0, "ok:eda8e57fa21332ea66eff2aaceffcafd0c5e6c9c7b4c488da23f63d27c1e8151"
            ":bbe1aa79848a1e9935e516b416c0465bd48c6376c130f11a2ab066601177ed82"),
        ("rotation u = 40 everywhere (t < 0: m = +0)",
         reencode(lambda p: None, coords_with(lambda c: c.__setitem__((slice(None), slice(4, 7)), 40))), 0,
         "ok:b0e7b1bd3adee00ee7878a85aac05c6924d9742c4e3b9a80403bc0384bd37adb"
         ":443e63bd37d08dbb52b5e0563089cd16e4a80883d2e0961cca10d6eec4d4f771"),
        ("rotation step 3e38 (Δ = ∞ where the shift is ≥ 1: NaN values, NaN t)",
         _chunk_edit(s0, "GQUA", lambda p: assign(p, rotation_step, f32(3e38))), 0,
         f"ok:{same_ints}:d8411d4d6df2571c2110dfb60a22f0ff8decd20c2a16a26193fdd15d4818d3ef"),
        ("GLAY voxel_size 1e−44 (subnormal h)", glay(lambda p: assign(p, 2, f32(1e-44))), 0,
         f"ok:{same_ints}:8b6ef8b5c9035b7cb1e4ddb53e8d98b3a95b367090da13f91796c19ca558dbc2"),
        ("GLAY voxel_size 3e38 (infinite positions)", glay(huge_voxel), 0,
         f"ok:{same_ints}:f562870456b7c287dd8f0bfaf0ddb7c0b37b3e7f9bc66f15b2b22716e5037dfe"),
        ("GHED origin[0] −3.4e38, voxel_size 3e38",
         _chunk_edit(glay(huge_voxel), "GHED", lambda p: assign(p, 15, f32(-3.4e38))), 0,
         f"ok:{same_ints}:2e9c2984c1535cfff5361115903b949a8057398d98a06ab5debe64532a78f33e"),
        ("rotation index 0 everywhere", rot_index(0), 0,
         "ok:c9433012823025260d19057fb9c1c0248c7740dd1948f4c23107b2dfef1c66a1"
         ":aa19a98b811ffb5a476d8c5f3a729949a969a5f1768e6bb705764ce6b8cce23b"),
        ("rotation index 3 everywhere", rot_index(3), 0,
         "ok:f38bdf56889332649eda29d2afd6a5990114c5072625272c39532110cfbb5c8f"
         ":61ba2d4ce6a547f6d3eae711620c6647aee47221d0fe174be51c34762a78f93f"),
    ]
    return cases


def test_explicit_profile_checks():
    """§3 on edited explicit-profile streams no vector covers: GLAY's checks in stream order,
    GQUA's values checked as they are read, other layers not parsed, the selected layer
    decoded as it is read, chunks of the other profile, the size class from u, |u| ≤ 2^24."""
    base = hashes(canonical_form(decode_bytes(_read("g-sh0.salvq"), 0)))
    for label, data, rate, want in explicit_cases():
        try:
            dec = decode_bytes(data, rate)
        except SalvqError as e:
            got = e.error_class
        else:
            h = hashes(canonical_form(dec))
            if "same decode" in label:
                assert h == base, label
            got = f"ok:{h[0]}:{h[1]}" if want.startswith("ok:") else "ok"
        assert got == want, f"{label}: {got}, expected {want}"


def _nth_payload(data: bytes, tag: str, nth: int) -> bytes:
    pos, k = 12, 0
    while pos + 8 <= len(data):
        n = int.from_bytes(data[pos:pos + 4], "little")
        if data[pos + 4:pos + 8] == tag.encode():
            if k == nth:
                return data[pos + 8:pos + 8 + n]
            k += 1
        pos += 12 + n
    raise KeyError(tag)


def _chunk_ends(data: bytes) -> list[tuple[str, int]]:
    """(tag, offset after the chunk) of each chunk of a stream."""
    pos, out = 12, []
    while pos + 8 <= len(data):
        n = int.from_bytes(data[pos:pos + 4], "little")
        pos += 12 + n
        out.append((data[pos - 8 - n:pos - 4 - n].decode(), pos))
    return out


def _progressive_reencode(data: bytes, gref_edit=None, target=None, counts=None) -> bytes:
    """Re-encodes every GRSY of the progressive stream `data` (§3.8.2, tools/reencode.py) after
    `gref_edit(l, payload)` edits refinement l's GREF (l = 1 …), with the values
    `target(l, ref, old_u, old_w, u, w)` returns (default: the stream's own refined values u, w;
    old_u, old_w the previous layer's): the new stream."""
    sys.path.insert(0, os.path.join(HERE, "..", "tools"))
    from reencode import encode_grsy
    from salvq_py.explicit import parse_glay, parse_gref
    from salvq_py.tiles import parse_tils
    h = decode_bytes(data).head
    rates = h.layer_rates()
    decs = [decode_bytes(data, r).integers for r in rates]
    lay = parse_glay(_payload(data, "GLAY"), h)
    tils = parse_tils(_payload(data, "TILS"), h.N, lay.coord_bits)
    vox, cls = decs[0]["gaussian.voxel"], decs[0]["symbols.size_class"]
    old_u, old_w = decs[0]["symbols.coordinates"], decs[0]["symbols.refinement"]
    E = list(lay.refine)
    for l in range(1, len(rates)):
        if gref_edit is not None:
            data = _chunk_edit(data, "GREF", lambda p: gref_edit(l, p), l - 1)
        ref = parse_gref(_nth_payload(data, "GREF", l - 1), h, lay.coord_bits, E)
        u, w = decs[l]["symbols.coordinates"], decs[l]["symbols.refinement"]
        if target is not None:
            u, w = target(l, ref, old_u, old_w, u, w)
        grsy = encode_grsy(h, ref, tils, vox, old_u, u, cls, old_w, w, (counts or {}).get(l))
        data = _chunk_edit(data, "GRSY", lambda p: grsy, l - 1)
        old_u, old_w = u, w
        E = [e + r for e, r in zip(E, ref.refine)]
    return data


def test_progressive_reencoded():                       # §3.8.2 (0.15)
    """Both progressive vectors, each refinement's values decoded by salvq_py and re-encoded by
    tools/reencode.py (§3.8.2 read from the encoder's side: old cell centre, residual, context
    classes, sh_rest count up to the last nonzero symbol), give the streams byte for byte."""
    for name in ("g-sh3-progressive", "g-sh0-progressive-skip"):
        data = _read(f"{name}.salvq")
        assert _progressive_reencode(data) == data, name


def test_progressive_region():                          # §10.3.1 with §3.8 (0.15)
    """A region decode of a progressive stream selects tiles by the full layer's TILS and
    voxel_size (a refinement has neither) and leaves the other tiles' bodies undecoded in GATT
    and in every GRSY decoded: a fault in one is not reported, while a whole decode reports it
    (the reference decoder agrees on all of these)."""
    data = _read("g-sh3-progressive.salvq")
    box = "-1e9,-1e9,-1e9,0.0,1e9,1e9"
    from salvq_py.explicit import parse_glay
    from salvq_py.tiles import parse_tils
    head = decode_bytes(data).head
    tiles = parse_tils(_payload(data, "TILS"), head.N, parse_glay(_payload(data, "GLAY"), head).coord_bits)
    T = len(tiles)
    base = {r: decode_bytes(data, r, region=box) for r in (2, 1, 0)}
    sel = base[0].tiles
    assert 0 < len(sel) < T and all(base[r].tiles == sel for r in base)
    out = [t for t in range(T) if t not in sel][0]

    def zero_top(p):                       # tile `out`'s body: a zero top word (§6.2.6 step 2)
        lens = [int.from_bytes(p[1 + 4 * i:5 + 4 * i], "little") for i in range(T)]
        at = 1 + 4 * T + sum(lens[:out])
        p[at:at + 4] = bytes(4)

    for tag, nth in (("GATT", 0), ("GRSY", 0), ("GRSY", 1)):
        broken = _chunk_edit(data, tag, zero_top, nth)
        for r in (2, 1, 0):
            dec = decode_bytes(broken, r, region=box)
            assert hashes(canonical_form(dec)) == hashes(canonical_form(base[r])), (tag, nth, r)
        try:
            decode_bytes(broken, 0)
            raise AssertionError(f"{tag} {nth}: the whole decode did not see the fault")
        except SalvqError as e:
            assert e.error_class == "AnsStreamInvalid", (tag, nth, e)


def progressive_cases() -> list[tuple[str, bytes, int, str]]:
    """Edited progressive streams (§3.8, 0.15) that no vector covers, as explicit_cases: (label,
    stream, rate, expected class, "ok" or "ok:<integer-domain hash>:<float hash>"). The
    vectors' refinements never predict (every GREF `predict` is 0), never reach a wide scale or
    context classes above 6, and use one factor per refinement; here GREF predicts, reaches wide
    scales, mixes factors 1, 2 (even), 255 and the most position bits §3.8.1 allows, and breaks
    §3.8.1's and §3.8.2's rules. Each expectation is the reference decoder's (0.15,
    `tools/probe_reference.py` reruns them), which salvq_py matches."""
    from salvq_py.explicit import parse_glay, rest_count_bits
    from salvq_py.tiles import parse_tils
    s3, s0 = _read("g-sh3-progressive.salvq"), _read("g-sh0-progressive-skip.salvq")
    h3, h0 = decode_bytes(s3).head, decode_bytes(s0).head
    lay3, lay0 = parse_glay(_payload(s3, "GLAY"), h3), parse_glay(_payload(s0, "GLAY"), h0)
    coord3, coord0, E0 = lay3.coord_bits, lay0.coord_bits, list(lay0.refine)
    body3 = 1 + 4 * len(parse_tils(_payload(s3, "TILS"), h3.N, coord3))   # GRSY: tile 0's body
    rng = np.random.RandomState(2026)

    def assign(p, at, b):
        p[at:at + len(b)] = b

    def gref_at(h):        # offsets in a GREF payload (§3.8.1)
        G = h.G
        return dict(pred=1, refine=2, factor=6, offset=6 + 4 * G, predict=6 + 8 * G,
                    freq=6 + 9 * G, table=6 + 9 * G + 2 * ((1 << rest_count_bits(h)) - 1))

    a3, a0 = gref_at(h3), gref_at(h0)

    def predict_all(at):
        return lambda l, p: assign(p, at["predict"], b"\x01" * (at["freq"] - at["predict"]))

    def wide(at):
        def edit(l, p):
            for i in range(at["table"], len(p)):
                p[i] = min(p[i] + 50, 127)
        return edit

    def coarse_pred(at):   # pred_level = coord_bits: a reference whenever the classes agree
        def edit(l, p):
            p[at["pred"]] = coord3
            assign(p, at["predict"], b"\x01" * (at["freq"] - at["predict"]))
        return edit

    def mixed_factors(l, p):
        # g-sh0-progressive-skip: factor[g][c]: 1 for the scale group in class 0, 2 in class 1,
        # 255 in class 2; opacity 1 everywhere; the other groups as they were (17)
        f = a0["factor"]
        assign(p, f, bytes([1, 2, 255, 17, 1, 1, 1, 1]))
        assign(p, a0["predict"], b"\x01\x00\x01\x01")

    def most_bits(l, p):   # refine[c] = 24 − coord_bits − E[c] (the most §3.8.1 allows)
        assign(p, a0["refine"], bytes(24 - coord0 - e for e in E0))

    def random_target(l, ref, old_u, old_w, u, w):
        """New values around the old cells' centres: u' = u·m + r, r in −40 … 40 (0 where the
        factor is 1), w' = w·2^e + e random bits."""
        cls = decode_bytes(s0).integers["symbols.size_class"].astype(np.int64)
        offs, dims = h0.group_offsets(), h0.group_dims()
        new_u = old_u.astype(np.int64).copy()
        for g, d in enumerate(dims):
            m = np.array(ref.factor[g], np.int64)[cls][:, None]
            r = rng.randint(-40, 41, (h0.N, d)) * (m > 1)
            new_u[:, offs[g]:offs[g] + d] = old_u[:, offs[g]:offs[g] + d] * m + r
        e = np.array(ref.refine, np.int64)[cls][:, None]
        new_w = (old_w.astype(np.int64) << e) + rng.randint(0, 1 << 20, (h0.N, 3)) % (1 << e)
        return new_u.astype(np.int32), new_w.astype(np.int32)

    def coordinate(value):
        def t(l, ref, old_u, old_w, u, w):
            u = u.copy()
            u[100, 8] = value      # sh_dc of Gaussian 100: factor 3 at rate 1, kept (1) at rate 0
            return u, w
        return t

    cases = [
        ("GREF predict all 1, GRSY re-encoded (same values), rate 0",
         _progressive_reencode(s3, predict_all(a3)), 0,
         "ok:79aefb9398df6bcbaeac603e0244fce4b32324fb556579c9bb6e87357f9bbb8a"
         ":3f342b49d3bba146ed71524eed2abc901b167a18618a5debff02166604ac1aa9"),
        ("GREF predict all 1, pred_level = coord_bits, re-encoded, rate 1",
         _progressive_reencode(s3, coarse_pred(a3)), 1,
         "ok:0c45d87aa45311a7d63fe4c776abd7019fb2880a1c01a84fb13b535c5d5e1d81"
         ":90ea16983dcfb643fca210edbc5f472a00c108bb0fc6cc263b4f535054194bae"),
        ("GREF scale_table + 50 (wide scales), re-encoded, rate 0",
         _progressive_reencode(s3, wide(a3)), 0,
         "ok:79aefb9398df6bcbaeac603e0244fce4b32324fb556579c9bb6e87357f9bbb8a"
         ":3f342b49d3bba146ed71524eed2abc901b167a18618a5debff02166604ac1aa9"),
        ("GREF factors 1, 2, 255 and predict, new values, rate 0",
         _progressive_reencode(s0, mixed_factors, random_target), 0,
         "ok:a2226876988fff0e58324dc2875758ee536cccb358090543f88eb65f03e80ddf"
         ":72f103538453de1e506f73379a870d4ea0d1eba6c04db8d553aaba9f867ae0ae"),
        ("GREF refine at 24 − coord_bits − E[c], predict 1, new values, rate 0",
         _progressive_reencode(s0, lambda l, p: (most_bits(l, p), predict_all(a0)(l, p)),
                               random_target), 0,
         "ok:2835e3e9628f9ec67904b6c88a6211b9b6413b1aef4152c09fab828dc0f7665e"
         ":c09f9476d8f37a04b399504ed110da2244a6733360cbc73ff1d6023936e2b68d"),
        ("GREF refine[0] one above 24 − coord_bits − E[0]",
         _chunk_edit(s0, "GREF", lambda p: assign(p, a0["refine"], bytes([25 - coord0 - E0[0]]))), 0,
         "FieldOutOfRange"),
        ("GRSY coordinate 2^24, re-encoded", _progressive_reencode(s3, target=coordinate(1 << 24)), 0,
         "ok:53407bf8084a1fc443ed73b2466b5eefbdf828b4f3dd228fc0f3194bcfb5c710"
         ":8ff4c2ab5fb79cd211bcb4c835037dc918939ae1af493cb16acc136a9e2b93cb"),
        ("GRSY coordinate −2^24 − 1, re-encoded",
         _progressive_reencode(s3, target=coordinate(-(1 << 24) - 1)), 0, "ValueInvalid"),
        ("GRSY rest count 63 > 45 (Gaussian 7), re-encoded",
         _progressive_reencode(s3, counts={1: {7: 63}}), 0, "ValueInvalid"),
        ("GREF factor[0][0] = 0 and scale_offset[0][0] = 64 (factor first)",
         _chunk_edit(s3, "GREF", lambda p: (assign(p, a3["factor"], b"\0"), assign(p, a3["offset"], b"\x40"))),
         0, "FieldOutOfRange"),
        ("GREF scale_offset[0][0] = −64 and predict[0] = 2",
         _chunk_edit(s3, "GREF", lambda p: (assign(p, a3["offset"], b"\xc0"), assign(p, a3["predict"], b"\x02"))),
         0, "ValueInvalid"),
        ("GREF pred_level = coord_bits + 1 and refine[0] = 255",
         _chunk_edit(s3, "GREF", lambda p: (assign(p, 1, bytes([coord3 + 1])), assign(p, 2, b"\xff"))), 0, "FieldOutOfRange"),
        ("GREF one byte longer", _chunk_edit(s3, "GREF", lambda p: p + b"\0"), 0, "ChunkSizeMismatch"),
        ("GREF coding_method 1", _chunk_edit(s3, "GREF", lambda p: assign(p, 0, b"\x01")), 0,
         "UnknownCodingMethod"),
        ("GRSY coding_method 0", _chunk_edit(s3, "GRSY", lambda p: assign(p, 0, b"\x00")), 0,
         "UnknownCodingMethod"),
        ("GRSY empty", _chunk_edit(s3, "GRSY", lambda p: bytearray()), 0, "ChunkSizeMismatch"),
        ("layer 1's GREF coding_method 5, rate 2 (not parsed)",
         _chunk_edit(s3, "GREF", lambda p: assign(p, 0, b"\x05"), 0), 2,
         "ok:fdbcd4397678552ff3d251fe698ae0eb8a510f05e7c8a46832a8193491573893"
         ":1163293e47c627c7288b2ef9c110ff8308e54c183f110907c8494a53f9d74b53"),
        ("layer 2's GREF coding_method 5, rate 1 (not parsed)",
         _chunk_edit(s3, "GREF", lambda p: assign(p, 0, b"\x05"), 1), 1,
         "ok:0c45d87aa45311a7d63fe4c776abd7019fb2880a1c01a84fb13b535c5d5e1d81"
         ":90ea16983dcfb643fca210edbc5f472a00c108bb0fc6cc263b4f535054194bae"),
        ("layer 1's GREF coding_method 5, rate 1", _chunk_edit(s3, "GREF", lambda p: assign(p, 0, b"\x05"), 0),
         1, "UnknownCodingMethod"),
        ("layer 1's GRSY broken, a byte after SEND (decoded as read), rate 1",
         _chunk_edit(s3, "GRSY", lambda p: assign(p, body3, bytes(4)), 0) + b"\0", 1, "AnsStreamInvalid"),
        ("layer 1's GRSY broken, rate 2", _chunk_edit(s3, "GRSY", lambda p: assign(p, body3, bytes(4)), 0),
         2, "ok:fdbcd4397678552ff3d251fe698ae0eb8a510f05e7c8a46832a8193491573893"
            ":1163293e47c627c7288b2ef9c110ff8308e54c183f110907c8494a53f9d74b53"),
        ("ancillary chunk between GREF and GRSY", _chunk_insert(s3, "GREF", "encd", b"x"), 0,
         "ok:79aefb9398df6bcbaeac603e0244fce4b32324fb556579c9bb6e87357f9bbb8a"
         ":3f342b49d3bba146ed71524eed2abc901b167a18618a5debff02166604ac1aa9"),
        ("GREF inserted after a layered stream's first GATT",
         _chunk_insert(_read("g-sh3-rates.salvq"), "GATT", "GREF", b"\0"), 0, "ChunkOrder"),
        ("rate 1 of rates 0 and 2", s0, 1, "RateNotCoded"),
        ("g-sh0 (one rate) with head_flags 1: a full layer and no refinement",
         _chunk_edit(_read("g-sh0.salvq"), "GHED", lambda p: assign(p, 6, b"\x01")), 0,
         "ok:dbd4a52fe78c627903697f3000665a2ab33472f610cc82d70213b3b65df7deb7"
         ":f2d7d010a90d7730629162d68cd661b756f1313f2194f95361fc45023d161b00"),
    ]
    return cases


def test_progressive_checks():                          # §3.8 (0.15)
    """§3.8 on edited progressive streams no vector covers (progressive_cases)."""
    for label, data, rate, want in progressive_cases():
        try:
            dec = decode_bytes(data, rate)
        except SalvqError as e:
            got = e.error_class
        else:
            h = hashes(canonical_form(dec))
            got = f"ok:{h[0]}:{h[1]}" if want.startswith("ok:") else "ok"
        assert got == want, f"{label}: {got}, expected {want}"


def _extract_progressive(data: bytes, rate: int) -> bytes:
    """§3.7's extraction from a progressive stream: the prefix up to the end of the rate's
    section (from its GLAY or GREF to the next GREF or SEND), GHED's rate_mask keeping the bits
    of the rate and the rates above it, then SEND."""
    rates = decode_bytes(data).head.layer_rates()
    layer = rates.index(rate)
    ends = _chunk_ends(data)
    start = [i for i, (t, _) in enumerate(ends) if t in ("GLAY", "GREF")][layer]
    stop = next(i for i, (t, _) in enumerate(ends) if i > start and t in ("GREF", "SEND"))
    mask = sum(1 << r for r in rates[:layer + 1])
    out = _chunk_edit(data[:ends[stop - 1][1]], "GHED",
                      lambda p: p.__setitem__(slice(7, 15), mask.to_bytes(8, "little")))
    return out + bytes(4) + b"SEND" + crc32c(b"SEND").to_bytes(4, "little")


def test_progressive_extraction_and_prefix():           # §3.7, §3.8.4 (0.15)
    """A progressive stream's extraction (§3.7: a prefix, rate_mask cut, SEND; the reference's
    `salvq extract` writes these bytes for every rate of both vectors) decodes to the same
    canonical form as the whole stream at that rate, by default at that rate. A stream cut
    anywhere (§3.8.4) is an error without the caller's consent (Truncated or
    ChunkLengthPastEnd); with it, one cut after the full layer's GATT decodes to the last layer
    whose chunks are all present, or the selected one when that is complete, bit-exactly."""
    for name in ("g-sh3-progressive", "g-sh0-progressive-skip"):
        data = _read(f"{name}.salvq")
        head = decode_bytes(data).head
        rates = head.layer_rates()
        whole = {r: hashes(canonical_form(decode_bytes(data, r))) for r in rates}
        for r in rates:
            ext = _extract_progressive(data, r)
            dec = decode_bytes(ext)
            assert dec.rate == r and hashes(canonical_form(dec)) == whole[r], (name, r)
            assert dec.head.progressive and not dec.prefix
        ends = _chunk_ends(data)
        gatt_end = next(e for t, e in ends if t == "GATT")
        complete = [e for t, e in ends if t == "GRSY"]            # where layer 1, 2, … end
        cuts = sorted({e for _, e in ends[:-1]} | {ends[-1][1] - 3}
                      | {(a + b) // 2 for (_, a), (_, b) in zip(ends, ends[1:])})
        for cut in cuts:
            part = data[:cut]
            # the finest rate at every cut; a coarser one where the cut is after the full layer
            for want in [rates[-1]] + (rates[:-1] if cut > gatt_end else []):
                if want == rates[-1]:
                    try:
                        decode_bytes(part, want)
                        raise AssertionError(f"{name} cut at {cut}: decoded without consent")
                    except SalvqError as e:
                        assert e.error_class in ("Truncated", "ChunkLengthPastEnd"), (name, cut, e)
                try:
                    dec = decode_bytes(part, want, prefix=True)
                except SalvqError as e:
                    assert cut < gatt_end and e.error_class in ("Truncated", "ChunkLengthPastEnd"), \
                        (name, cut, want, e)
                    continue
                assert cut >= gatt_end, (name, cut)
                last = sum(1 for e in complete if e <= cut)        # complete refinements
                got = rates[min(last, rates.index(want))]
                assert dec.prefix and dec.rate == got, (name, cut, want, dec.rate)
                assert hashes(canonical_form(dec)) == whole[got], (name, cut, want)
    cut = _read("x-g-progressive-cut.salvq")                  # cut inside its refinement's GRSY
    dec = decode_bytes(cut, 0, prefix=True)
    assert dec.prefix and dec.rate == dec.head.layer_rates()[0]


def _payload(data: bytes, tag: str) -> bytes:
    pos = 12
    while True:
        n = int.from_bytes(data[pos:pos + 4], "little")
        if data[pos + 4:pos + 8] == tag.encode():
            return data[pos + 8:pos + 8 + n]
        pos += 12 + n


def test_rest_count_reencoded():                       # §3.5 (0.13)
    """g-sh3-rates' rate-0 layer, its values decoded by salvq_py and re-encoded by
    tools/reencode.py (which writes each Gaussian's sh_rest count as the values up to its last
    nonzero symbol, then only those values), is the stream's GATT payload byte for byte: the
    count's tree and the uncoded zeros read as the reference encoder wrote them."""
    sys.path.insert(0, os.path.join(HERE, "..", "tools"))
    from reencode import encode_gatt
    from salvq_py.explicit import parse_glay
    from salvq_py.tiles import parse_tils
    s3 = _read("g-sh3-rates.salvq")
    base = decode_bytes(s3, 0)
    h, ints = base.head, base.integers
    lay = parse_glay(_payload(s3, "GLAY"), h)
    assert h.G == 5 and len(lay.rest_count_freq) == 63
    tils = parse_tils(_payload(s3, "TILS"), h.N, lay.coord_bits)
    gatt = encode_gatt(h, lay, tils, ints["gaussian.voxel"], ints["symbols.coordinates"],
                       ints["symbols.rotation_index"], ints["symbols.size_class"],
                       ints["symbols.refinement"])
    assert gatt == _payload(s3, "GATT")


def test_wide_scales_reencoded():                      # §6.3.6, §3.5 (0.14)
    """g-wide-scales (scale indices 64 … 127 through scale_table and scale_offset, every number
    of low bits 1 … 8), its values decoded by salvq_py and re-encoded by tools/reencode.py, is
    the stream's GATT payload byte for byte: the high part and the low bits in the order the
    reference encoder wrote."""
    sys.path.insert(0, os.path.join(HERE, "..", "tools"))
    from reencode import encode_gatt
    from salvq_py.explicit import parse_glay
    from salvq_py.tiles import parse_tils
    from salvq_py.ans import AnsDecoder
    s = _read("g-wide-scales.salvq")
    # The vector must keep exercising every number of low bits, b = 1 … 8.
    seen, original = set(), AnsDecoder.decode_wide
    def counting(self, k):
        seen.add((k - 56) >> 3)
        return original(self, k)
    AnsDecoder.decode_wide = counting
    try:
        base = decode_bytes(s, 0)
    finally:
        AnsDecoder.decode_wide = original
    assert seen == set(range(1, 9)), f"low-bit counts used: {sorted(seen)}"
    h, ints = base.head, base.integers
    lay = parse_glay(_payload(s, "GLAY"), h)
    assert max(max(row) for row in lay.scale_table) >= 64
    tils = parse_tils(_payload(s, "TILS"), h.N, lay.coord_bits)
    gatt = encode_gatt(h, lay, tils, ints["gaussian.voxel"], ints["symbols.coordinates"],
                       ints["symbols.rotation_index"], ints["symbols.size_class"],
                       ints["symbols.refinement"])
    assert gatt == _payload(s, "GATT")


def test_valid_vectors():
    for vec in _manifest():
        if vec["kind"] == "valid":
            check_valid(vec)


def test_must_fail_vectors():
    for vec in _manifest():
        if vec["kind"] != "valid":
            check_must_fail(vec)


def main() -> int:
    failed = 0
    for t in (test_crc32c_check_value, test_tables_match_data_files, test_ans_golden_vector,
              test_ans_uniform_values, test_mlps_precision_checks, test_explicit_profile_checks,
              test_rest_count_reencoded, test_ans_wide_scales, test_wide_scales_reencoded,
              test_region_decodes, test_progressive_checks, test_progressive_reencoded,
              test_progressive_extraction_and_prefix, test_progressive_region):
        try:
            t()
            print(f"pass  {t.__name__}")
        except AssertionError as e:
            failed += 1
            print(f"FAIL  {t.__name__}: {e}")
    slowest = (0.0, "")
    for vec in _manifest():
        t0 = time.perf_counter()
        try:
            if vec["kind"] == "valid":
                how = ", ".join(check_valid(vec))
            else:
                how = check_must_fail(vec)
            print(f"pass  {vec['name']:<32} {how}")
        except AssertionError as e:
            failed += 1
            print(f"FAIL  {vec['name']:<32} {e}")
        except Exception as e:  # noqa: BLE001
            failed += 1
            print(f"FAIL  {vec['name']:<32} {type(e).__name__}: {e}")
        dt = time.perf_counter() - t0
        slowest = max(slowest, (dt, vec["name"]))
    print(f"{'all passed' if not failed else f'{failed} failed'}; slowest: {slowest[1]} {slowest[0]:.2f} s")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
