"""Differential fuzzing against the reference decoder binary (optional; needs it).

    python3 tools/diff_fuzz.py REF_BINARY VECTORS_DIR [ITERATIONS] [SEED] [FILTER]

FILTER keeps the valid vectors whose name contains it (e.g. `g-` for the explicit profile).

Mutates valid conformance streams (a byte of a chunk payload, with the CRC recomputed so the
error reaches the payload's decoder; a payload cut or grown, length and CRC fixed; a HEAD
field) and checks that salvq_py and the reference agree: the same error class, or the same
canonical decode (both hashes)."""
from __future__ import annotations

import json
import os
import random
import re
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
from salvq_py import SalvqError, decode_bytes, hashes  # noqa: E402
from salvq_py.canonical import canonical_form, read_safetensors  # noqa: E402
from salvq_py.container import crc32c  # noqa: E402


def chunks(data: bytes):
    pos = 12
    out = []
    while pos + 8 <= len(data):
        n = int.from_bytes(data[pos:pos + 4], "little")
        out.append((pos, n, data[pos + 4:pos + 8]))
        pos += 12 + n
    return out


def rebuild(data: bytes, ci: int, new_payload: bytes) -> bytes:
    pos, n, tag = chunks(data)[ci]
    crc = crc32c(new_payload, crc32c(tag))
    return (data[:pos] + len(new_payload).to_bytes(4, "little") + tag + new_payload
            + crc.to_bytes(4, "little") + data[pos + 12 + n:])


def mutate(data: bytes, rng: random.Random) -> tuple[bytes, str]:
    cs = chunks(data)
    ci = rng.randrange(len(cs))
    pos, n, tag = cs[ci]
    payload = bytearray(data[pos + 8:pos + 8 + n])
    kind = rng.choice(["byte", "byte", "byte", "bit", "cut", "grow", "word0"])
    if kind in ("byte", "bit") and n:
        i = rng.randrange(n)
        if kind == "byte":
            payload[i] = rng.randrange(256)
        else:
            payload[i] ^= 1 << rng.randrange(8)
    elif kind == "cut" and n:
        payload = payload[:rng.randrange(n)]
    elif kind == "grow":
        payload += bytes(rng.randrange(256) for _ in range(rng.choice([1, 4, 8])))
    elif kind == "word0" and n >= 8:
        i = rng.randrange(0, n - 3)
        payload[i:i + 4] = rng.choice([b"\0\0\0\0", b"\xff\xff\xff\xff", b"\x01\0\0\0"])
    return rebuild(data, ci, bytes(payload)), f"{tag.decode()} {kind}"


def run_ref(ref: str, data: bytes, rate: int):
    with tempfile.TemporaryDirectory() as td:
        src = os.path.join(td, "in.salvq")
        dst = os.path.join(td, "out.st")
        with open(src, "wb") as fh:
            fh.write(data)
        p = subprocess.run([ref, "decode", src, "-o", dst, "--rate", str(rate), "--canonical"],
                           capture_output=True, text=True, timeout=120)
        if p.returncode == 0:
            return ("ok", hashes(read_safetensors(dst)))
        m = re.search(r"error\[(\w+)\]: (.*)", p.stderr)
        return ("err", m.group(1) if m else p.stderr.strip(), m.group(2) if m else "")


def run_mine(data: bytes, rate: int):
    try:
        return ("ok", hashes(canonical_form(decode_bytes(data, rate))))
    except SalvqError as e:
        return ("err", e.error_class, e.message)


def main():
    ref, vdir = sys.argv[1], sys.argv[2]
    iters = int(sys.argv[3]) if len(sys.argv) > 3 else 200
    rng = random.Random(int(sys.argv[4]) if len(sys.argv) > 4 else 1)
    manifest = json.load(open(os.path.join(vdir, "manifest.json")))
    only = sys.argv[5] if len(sys.argv) > 5 else ""
    bases = [(v["file"], v["decodes"][0]["rate"]) for v in manifest["vectors"]
             if v["kind"] == "valid" and v["bytes"] < 20000 and only in v["name"]]
    disagree = 0
    for it in range(iters):
        fname, rate = rng.choice(bases)
        data = open(os.path.join(vdir, fname), "rb").read()
        mutated, what = mutate(data, rng)
        r, m = run_ref(ref, mutated, rate), run_mine(mutated, rate)
        if r[:2] != m[:2]:
            disagree += 1
            print(f"DISAGREE {fname} ({what}): ref {r} / mine {m}")
            with open(os.path.join(tempfile.gettempdir(), f"salvq-disagree-{it}.salvq"), "wb") as fh:
                fh.write(mutated)
    print(f"{iters} mutations, {disagree} disagreements")


if __name__ == "__main__":
    main()
