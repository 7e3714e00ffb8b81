"""Normative integer tables.

* Table 5-2 STEP_FACTOR (§5.4 step 1), checked against the SHA-256 §5.4 gives for
  `spec/tables/step_factor.txt`.
* Table 6-1 scale grid (§6.3.1): `sigma_q16` and `threshold_q16` integers.
* §6.3.2 - §6.3.4: the 64 frequency tables of the discretized Gaussian, built by the normative
  integer procedure (not loaded from a file) and checked against the SHA-256 of §6.3.5.
"""
from __future__ import annotations

import bisect
import hashlib

P = 16                      # coder precision (§6.2)
TAIL_Q4 = 80                # §6.3.2
R_MAX = 127                 # §6.3.2
SCALE_COUNT = 64            # §6.3.1
SCALE_INDEX_COUNT = 128      # §6.3.6 (0.14): scale indices 0 … 127 in all, 64 … 127 wide

# Table 5-2: STEP_FACTOR[a + 64] = round((1 + tanh(a/16)) * 2^16), a = -64 .. 64.
STEP_FACTOR = (
    44, 50, 56, 64, 72, 82, 93, 105, 119, 135, 153, 174, 197, 223, 253, 286, 324, 367, 416,
    471, 533, 604, 684, 775, 877, 993, 1124, 1273, 1440, 1629, 1843, 2085, 2357, 2665, 3012,
    3402, 3842, 4337, 4893, 5517, 6216, 7000, 7876, 8853, 9943, 11154, 12498, 13984, 15624,
    17428, 19405, 21564, 23911, 26452, 29190, 32124, 35251, 38563, 42051, 45698, 49485, 53390,
    57386, 61445, 65536, 69627, 73686, 77682, 81587, 85374, 89021, 92509, 95821, 98948,
    101882, 104620, 107161, 109508, 111667, 113644, 115448, 117088, 118574, 119918, 121129,
    122219, 123196, 124072, 124856, 125555, 126179, 126735, 127230, 127670, 128060, 128407,
    128715, 128987, 129229, 129443, 129632, 129799, 129948, 130079, 130195, 130297, 130388,
    130468, 130539, 130601, 130656, 130705, 130748, 130786, 130819, 130849, 130875, 130898,
    130919, 130937, 130953, 130967, 130979, 130990, 131000, 131008, 131016, 131022, 131028,
)
STEP_FACTOR_SHA256 = "9cc4994547c6dbe95d5f95725c93b2aa23f9af3f31b319a5a5aa971d7ffbd92d"
# The comment line of the data file. The spec does not give its text (see README, spec gaps):
# it is copied from spec/tables/step_factor.txt so that the SHA-256 can be checked.
_STEP_FACTOR_COMMENT = ("# salvq spec Table 5-2: STEP_FACTOR[a + 64] = "
                        "round((1 + tanh(a / 16)) * 2^16), a = -64 .. 64")

# Table 6-1.
SIGMA_Q16 = (
    8192, 8933, 9742, 10624, 11585, 12634, 13777, 15024, 16384, 17867, 19484, 21247, 23170,
    25268, 27554, 30048, 32768, 35734, 38968, 42495, 46341, 50535, 55109, 60097, 65536, 71468,
    77936, 84990, 92682, 101070, 110218, 120194, 131072, 142935, 155872, 169979, 185364,
    202141, 220436, 240387, 262144, 285870, 311744, 339959, 370728, 404281, 440872, 480774,
    524288, 571740, 623487, 679917, 741455, 808563, 881744, 961548, 1048576, 1143480, 1246974,
    1359835, 1482910, 1617125, 1763488, 1923097,
)
# THRESHOLD_Q16[j] = theta_j for j = 1 .. 63 (index 0 unused: k = 0 has no threshold).
THRESHOLD_Q16 = (
    None, 8555, 9329, 10173, 11094, 12098, 13193, 14387, 15689, 17109, 18658, 20347, 22188,
    24196, 26386, 28774, 31379, 34219, 37316, 40693, 44376, 48393, 52773, 57549, 62757, 68438,
    74632, 81386, 88752, 96785, 105545, 115098, 125515, 136875, 149263, 162773, 177505, 193571,
    211090, 230195, 251030, 273750, 298527, 325546, 355010, 387141, 422180, 460391, 502060,
    547500, 597053, 651091, 710020, 774282, 844361, 920782, 1004120, 1095000, 1194106,
    1302182, 1420040, 1548564, 1688722, 1841564,
)
GAUSSIAN_TABLES_SHA256 = "939b9a00d2eb98c9999b610b33da3824dece1d6121a60309e3261fdd96e4dc63"
# §6.3.5 says "two comment lines starting with #" but not their text; copied from the file.
_GAUSSIAN_COMMENTS = (
    "# SALVQ Gaussian frequency tables (spec section 6.3): precision P = 16, TAIL = 80/16, "
    "R_MAX = 127",
    "# k sigma_q16 threshold_q16 R_k f(-R_k) ... f(R_k) f(ESCAPE)",
)

_C = 7359186146747302452          # floor(2^64 / sqrt(2 pi))
_X_MAX_Q32 = 25769803776          # 6 * 2^32


def radius(k: int) -> int:
    """§6.3.2: R_k = min(ceil_div(TAIL_Q4 * sigma_q16_k, 2^20), R_MAX)."""
    s = SIGMA_Q16[k]
    return min(-((-TAIL_Q4 * s) // (1 << 20)), R_MAX)


def gaussian_g(b2: int, s: int) -> int:
    """§6.3.3 steps 1-5: G(b2, s) = Phi(x) - 1/2 in Q64, x = b2 * 2^15 / s."""
    x = (b2 << 47) // s
    if x >= _X_MAX_Q32:
        return 1 << 63
    t = (x * _C) >> 32
    acc = t
    n = 1
    while True:
        t = (((t * x) >> 32) * x) // (n << 33)
        if t == 0:
            break
        if n & 1:
            acc -= t // (2 * n + 1)
        else:
            acc += t // (2 * n + 1)
        n += 1
    return min(max(acc, 0), 1 << 63)


def build_frequencies(k: int) -> list[int]:
    """§6.3.3 steps 6-7 and §6.3.4: frequencies of scale k in alphabet index order
    (u = -R .. R, then ESCAPE)."""
    s = SIGMA_Q16[k]
    r = radius(k)
    gt = [gaussian_g(1, s)]
    for u in range(1, r + 1):
        gt.append(max(gaussian_g(2 * u + 1, s), gt[u - 1]))
    mass_abs = [2 * gt[0]] + [gt[u] - gt[u - 1] for u in range(1, r + 1)]
    masses = [mass_abs[abs(u)] for u in range(-r, r + 1)]
    masses.append((1 << 64) - 2 * gt[r])
    a = 2 * r + 2
    w = (1 << P) - a
    f = [1 + ((m * w) >> 64) for m in masses]
    rem = (1 << P) - sum(f)
    assert 0 <= rem < a
    if rem & 1:
        f[r] += 1          # f(0): alphabet index 0 + R
        rem -= 1
    j = 1
    while rem > 0:
        f[r - j] += 1
        f[r + j] += 1
        rem -= 2
        j += 1
    assert sum(f) == 1 << P and min(f) >= 1
    return f


class ScaleTable:
    """One scale's alphabet: frequencies, cumulative frequencies and a lookup for §6.2.4 step 2."""

    __slots__ = ("k", "radius", "freq", "cum", "escape")

    def __init__(self, k: int, freq: list[int]):
        self.k = k
        self.radius = radius(k)
        self.freq = freq
        cum = [0]
        for f in freq:
            cum.append(cum[-1] + f)
        self.cum = cum
        self.escape = 2 * self.radius + 1

    def find(self, q: int) -> int:
        """The alphabet index s with cum[s] <= q < cum[s + 1]."""
        return bisect.bisect_right(self.cum, q) - 1


def render_gaussian_tables(freqs: list[list[int]]) -> bytes:
    """§6.3.5: the text of spec/tables/gaussian_tables.txt."""
    lines = list(_GAUSSIAN_COMMENTS)
    for k in range(SCALE_COUNT):
        th = "-" if k == 0 else str(THRESHOLD_Q16[k])
        lines.append(" ".join([str(k), str(SIGMA_Q16[k]), th, str(radius(k))]
                              + [str(v) for v in freqs[k]]))
    return ("\n".join(lines) + "\n").encode("ascii")


def render_step_factor() -> bytes:
    lines = [_STEP_FACTOR_COMMENT]
    for a in range(-64, 65):
        lines.append(f"{a} {STEP_FACTOR[a + 64]}")
    return ("\n".join(lines) + "\n").encode("ascii")


_TABLES: list[ScaleTable] | None = None


def scale_tables(verify: bool = True) -> list[ScaleTable]:
    """The 64 tables of §6.3, built once per process by the integer procedure."""
    global _TABLES
    if _TABLES is None:
        freqs = [build_frequencies(k) for k in range(SCALE_COUNT)]
        if verify:
            digest = hashlib.sha256(render_gaussian_tables(freqs)).hexdigest()
            if digest != GAUSSIAN_TABLES_SHA256:
                raise AssertionError(f"frequency tables differ from §6.3.5 (SHA-256 {digest})")
        _TABLES = [ScaleTable(k, freqs[k]) for k in range(SCALE_COUNT)]
    return _TABLES


def check_step_factor() -> None:
    digest = hashlib.sha256(render_step_factor()).hexdigest()
    if digest != STEP_FACTOR_SHA256:
        raise AssertionError(f"STEP_FACTOR differs from Table 5-2 (SHA-256 {digest})")
