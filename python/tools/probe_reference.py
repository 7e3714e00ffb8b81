"""Reproduce the places where salvq_py and the reference decoder were found to differ, or
where the reference showed what the spec leaves open (README, "Spec gaps found").

    python3 tools/probe_reference.py REF_BINARY VECTORS_DIR

Each probe edits a conformance vector (CRC recomputed; the selected layer re-encoded with
tools/reencode.py where the edit changes the prior) and prints both decoders' results."""
from __future__ import annotations

import os
import struct
import sys

sys.path.insert(0, os.path.dirname(__file__))
from diff_fuzz import chunks, rebuild, run_mine, run_ref  # noqa: E402
from reencode import reencode_layer  # noqa: E402
from salvq_py import decoder as D  # noqa: E402


def edit(data: bytes, tag: str, fn) -> bytes:
    for ci, (pos, n, t) in enumerate(chunks(data)):
        if t == tag.encode():
            p = bytearray(data[pos + 8:pos + 8 + n])
            fn(p)
            return rebuild(data, ci, bytes(p))
    raise KeyError(tag)


def show(ref, label, data, rate=0):
    r, m = run_ref(ref, data, rate), run_mine(data, rate)
    print(("same " if r[:2] == m[:2] else "DIFF ") + label)
    print("   reference:", r)
    print("   salvq_py: ", m)


def main():
    ref, vdir = sys.argv[1], sys.argv[2]
    load = lambda n: open(os.path.join(vdir, n + ".salvq"), "rb").read()  # noqa: E731

    # 1. §5.4 step 1 with E >= 64: a0 = 30, shift0 = 0, a1 = 30 on the three step rows (E = 68).
    for name, rate in (("usq-one-rate", 1), ("max-attributes", 63)):
        data = load(name)
        dec = D.decode_bytes(data, rate)
        cout = dec.dims.Cout

        def mlps(p):   # p[0] coding_method, p[1] context_precision (§1.6.2, 0.10)
            p[2], p[3] = 30, 0
            for o in range(cout - 3, cout):
                p[4 + o] = 30
        show(ref, f"{name}@{rate}: step-adjustment rows with E = 68 (§5.4 step 1)",
             reencode_layer(edit(data, "MLPS", mlps), rate, dec.symbols), rate)

    # 2. §1.4 step 4 order: scaling_lattice E8 on S = 6 (LatticeDimension) and coord_bits = 0.
    data = load("salvq-four-rates")

    def head(p):
        p[14] = 2      # scaling_lattice
        p[11] = 0      # coord_bits
    show(ref, "HEAD: E8 on S = 6 and coord_bits = 0 (§1.4 step 4: coord_bits comes first)",
         edit(data, "HEAD", head))

    def head2(p):
        p[13] = 5      # feat_lattice code out of range
        p[0:4] = b"\0\0\0\0"
    show(ref, "HEAD: feat_lattice = 5 and anchor_count = 0 (same class, different field)",
         edit(data, "HEAD", head2))

    # 3. §1.6.3: basis_s[1] = 0 and basis_v[0, 0] = NaN in the same basis.
    data = load("fs-salvq")
    d = D.decode_bytes(data).dims
    off = 1 + 4 + 4 * d.M      # feat group's first basis
    F = d.F

    def quan(p):
        s = off + 4 * F * F
        p[s + 4:s + 8] = struct.pack("<f", 0.0)
        v = s + 4 * F
        p[v:v + 4] = struct.pack("<I", 0x7FC00000)
    show(ref, "QUAN: basis_s[1] = 0 and basis_v[0, 0] = NaN (BasisSingular before or after v?)",
         edit(data, "QUAN", quan))

    # 4. The explicit profile (§3): the edited streams of tests/test_conformance.py.
    sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "tests"))
    os.environ.setdefault("SALVQ_VECTORS", vdir)
    from test_conformance import explicit_cases, progressive_cases
    for label, data, rate, want in explicit_cases():
        show(ref, f"explicit: {label} (expected {want})", data, rate)

    # 5. Progressive streams (§3.8, 0.15): the edited streams of tests/test_conformance.py.
    for label, data, rate, want in progressive_cases():
        show(ref, f"progressive: {label} (expected {want[:40]})", data, rate)


if __name__ == "__main__":
    main()
