"""Differential fuzzing of progressive explicit streams (§3.8, 0.15) against a reference binary.

    python3 tools/progressive_fuzz.py REF VECTORS [N] [SEED] [MODE]

MODE `mutate` (default): random payload mutations (tools/diff_fuzz.py's, CRCs recomputed) of
`g-sh3-progressive` and `g-sh0-progressive-skip`, decoded at a random coded rate (the rate
diff_fuzz.py takes is the first listed, the full layer's, and it skips streams over 20 000
bytes). MODE `gref`: every refinement re-encoded (tools/reencode.py's `encode_grsy`) with a
random valid `GREF` header (pred_level, refine up to §3.8.1's bound, factors 1 … 255 mixed,
scale offsets, predict, rest_count_freq, scale_table 0 … 127) and random refined values
around the old cells' centres. Same class or same hashes (§11.2) required; a disagreeing
stream is written to the temporary directory. Testing aid only."""
from __future__ import annotations

import os
import random
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(HERE, "..", "tests"))

import numpy as np  # noqa: E402

from diff_fuzz import mutate, run_mine, run_ref  # noqa: E402

NAMES = ("g-sh3-progressive", "g-sh0-progressive-skip")


def random_gref(rng, h, lay, E, p):
    """Fill GREF payload p (bytearray) with random valid fields; returns the new E."""
    from salvq_py.explicit import rest_count_bits
    G, L = h.G, rest_count_bits(h)
    p[1] = rng.randrange(0, lay.coord_bits + 1)
    refine = [min(rng.randrange(0, 4), 24 - lay.coord_bits - E[c]) for c in range(4)]
    p[2:6] = bytes(refine)
    p[6:6 + 4 * G] = bytes(rng.choice((1, 1, 2, 3, 4, 5, 17, 255, rng.randrange(1, 256)))
                           for _ in range(4 * G))
    p[6 + 4 * G:6 + 8 * G] = bytes(rng.randrange(-63, 64) & 0xFF for _ in range(4 * G))
    p[6 + 8 * G:6 + 9 * G] = bytes(rng.randrange(2) for _ in range(G))
    at = 6 + 9 * G
    for m in range((1 << L) - 1):
        p[at + 2 * m:at + 2 * m + 2] = rng.randrange(1, 1 << 16).to_bytes(2, "little")
    for i in range(at + 2 * ((1 << L) - 1), len(p)):
        p[i] = rng.randrange(128)
    return [e + r for e, r in zip(E, refine)]


def gref_trial(rng, nrng, vdir):
    from salvq_py import decode_bytes
    from salvq_py.explicit import parse_glay
    from test_conformance import _payload, _progressive_reencode
    name = rng.choice(NAMES)
    data = open(os.path.join(vdir, name + ".salvq"), "rb").read()
    h = decode_bytes(data).head
    lay = parse_glay(_payload(data, "GLAY"), h)
    cls = decode_bytes(data, h.layer_rates()[0]).integers["symbols.size_class"].astype(np.int64)
    E = [list(lay.refine)]

    def edit(l, p):
        E.append(random_gref(rng, h, lay, E[-1], p))

    def target(l, ref, old_u, old_w, u, w):
        offs, dims = h.group_offsets(), h.group_dims()
        new_u = old_u.astype(np.int64).copy()
        for g, d in enumerate(dims):
            m = np.array(ref.factor[g], np.int64)[cls][:, None]
            spread = rng.choice((0, 1, 3, 40, 1000))
            r = nrng.randint(-spread, spread + 1, (h.N, d)) * (m > 1)
            if g == 4:                          # sh_rest: zeros after a random count
                r[np.arange(d)[None, :] >= nrng.randint(0, d + 1, h.N)[:, None]] = 0
            new_u[:, offs[g]:offs[g] + d] = np.clip(old_u[:, offs[g]:offs[g] + d] * m + r,
                                                    -(1 << 24), 1 << 24)
        e = np.array(ref.refine, np.int64)[cls][:, None]
        new_w = (old_w.astype(np.int64) << e) + nrng.randint(0, 1 << 22, (h.N, 3)) % (1 << e)
        return new_u.astype(np.int32), new_w.astype(np.int32)

    return name, _progressive_reencode(data, edit, target), rng.choice(h.layer_rates())


def main():
    ref, vdir = sys.argv[1], sys.argv[2]
    n = int(sys.argv[3]) if len(sys.argv) > 3 else 100
    seed = int(sys.argv[4]) if len(sys.argv) > 4 else 1
    mode = sys.argv[5] if len(sys.argv) > 5 else "mutate"
    os.environ.setdefault("SALVQ_VECTORS", vdir)
    rng, nrng = random.Random(seed), np.random.RandomState(seed)
    rates = {"g-sh3-progressive": (2, 1, 0), "g-sh0-progressive-skip": (2, 0)}
    outcomes, disagree = {}, 0
    for it in range(n):
        if mode == "gref":
            name, data, rate = gref_trial(rng, nrng, vdir)
            what = "random GREF"
        else:
            name = rng.choice(NAMES)
            data, what = mutate(open(os.path.join(vdir, name + ".salvq"), "rb").read(), rng)
            rate = rng.choice(rates[name])
        r, m = run_ref(ref, data, rate), run_mine(data, rate)
        key = r[1] if r[0] == "err" else "ok"
        outcomes[key] = outcomes.get(key, 0) + 1
        if r[:2] != m[:2]:
            disagree += 1
            path = os.path.join(tempfile.gettempdir(), f"salvq-progressive-{mode}-{it}.salvq")
            with open(path, "wb") as fh:
                fh.write(data)
            print(f"DISAGREE {name}@{rate} ({what}): ref {r} / mine {m} ({path})")
    print(f"{n} trials, {disagree} disagreements; reference outcomes {outcomes}")
    return 1 if disagree else 0


if __name__ == "__main__":
    sys.exit(main())
