"""Conformance of salvq_py against conformance/vectors (spec §11), without the Rust binary.

Run with `python3 -m pytest python/tests` if pytest is installed, or directly:
`python3 python/tests/test_conformance.py`.

* valid vectors: every listed rate is decoded; the integer-domain hash (§11.2) must equal the
  manifest's; every tensor in the expected file must match (integer domain byte for byte,
  float tensors within the §11.3 tolerance); the float hash is reported (bit-exact or not).
* must-fail vectors: decoding must raise SalvqError with the manifest's error class.
"""
from __future__ import annotations

import json
import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))

import numpy as np  # noqa: E402

from salvq_py import SalvqError, decode_bytes  # noqa: E402
from salvq_py.ans import AnsDecoder  # noqa: E402
from salvq_py.canonical import (FLOAT_TENSORS, canonical_form, float_match, hashes,  # noqa: E402
                                read_safetensors)
from salvq_py.container import crc32c  # noqa: E402
from salvq_py.tables import check_step_factor, scale_tables  # noqa: E402

VECTORS = os.environ.get("SALVQ_VECTORS",
                         os.path.join(HERE, "..", "..", "conformance", "vectors"))


def _manifest():
    with open(os.path.join(VECTORS, "manifest.json")) as fh:
        return json.load(fh)["vectors"]


def _read(name):
    with open(os.path.join(VECTORS, name), "rb") as fh:
        return fh.read()


def check_valid(vec) -> list[str]:
    """Returns a list of notes; raises AssertionError on a failure."""
    notes = []
    data = _read(vec["file"])
    for dec in vec["decodes"]:
        rate = dec["rate"]
        form = canonical_form(decode_bytes(data, rate))
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
        return e.error_class
    raise AssertionError(f"{vec['name']}: decoded, expected {vec['error_class']}")


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
              test_mlps_precision_checks):
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
