"""Command line, §11.5 contract:  python3 -m salvq_py IN OUT [RATE] [REGION] [--prefix]

Writes the canonical form (§11.1; §11.6 for an explicit-profile stream) of IN decoded at RATE
to OUT as safetensors and exits 0; on a stream error prints `salvq_py: error[CLASS]: message`
to stderr and exits 1. REGION (`x0,y0,z0,x1,y1,z1`, also `--region X` anywhere) makes it a
region decode (§10.3.1, §11.7); a box with a NaN or with min > max on an axis, or a malformed
argument, is refused before the stream is read, with exit status 2 (the caller's error).
`--prefix` consents to decoding a progressive stream that ends early (§3.8.4) to its last
complete layer; the decoder then says so on stderr and names the rate it decoded."""
from __future__ import annotations

import os
import sys
import tempfile

from .canonical import canonical_form, write_safetensors
from .decoder import decode_file
from .errors import SalvqError
from .region import RegionError, parse_region

USAGE = ("usage: python3 -m salvq_py IN OUT [RATE] [REGION | --region x0,y0,z0,x1,y1,z1]"
         " [--prefix]")


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if any(a in ("-h", "--help") for a in argv):
        print(USAGE, file=sys.stderr)
        return 2
    region = None
    prefix = False
    pos = []
    i = 0
    while i < len(argv):
        a = argv[i]
        if a == "--prefix":                             # §3.8.4: the caller's consent
            prefix = True
            i += 1
            continue
        if a == "--region" or a.startswith("--region="):
            if region is not None:
                print(f"salvq_py: --region given twice\n{USAGE}", file=sys.stderr)
                return 2
            if a == "--region":
                if i + 1 == len(argv):
                    print(f"salvq_py: --region needs a value\n{USAGE}", file=sys.stderr)
                    return 2
                region = argv[i + 1]
                i += 2
            else:
                region = a[len("--region="):]
                i += 1
            continue
        pos.append(a)
        i += 1
    if region is None and (len(pos) == 4 or (len(pos) == 3 and "," in pos[2])):
        region = pos.pop()                              # IN OUT [RATE] REGION
    if len(pos) not in (2, 3):
        print(USAGE, file=sys.stderr)
        return 2
    src, dst = pos[0], pos[1]
    try:
        rate = int(pos[2]) if len(pos) == 3 else None
    except ValueError:
        print(f"salvq_py: rate {pos[2]!r} is not an integer\n{USAGE}", file=sys.stderr)
        return 2
    box = None
    if region is not None:
        try:
            box = parse_region(region)                  # §10.3.1: before reading the stream
        except RegionError as e:
            print(f"salvq_py: no box: {e}", file=sys.stderr)
            return 2
    try:
        decoded = decode_file(src, rate, region=box, prefix=prefix)
        form = canonical_form(decoded)
    except SalvqError as e:
        print(f"salvq_py: error[{e.error_class}]: {e.message}", file=sys.stderr)
        return 1
    except OSError as e:
        print(f"salvq_py: error[Io]: {e}", file=sys.stderr)
        return 1
    if getattr(decoded, "prefix", False):
        print(f"salvq_py: note: the progressive stream ends before SEND; decoded rate {decoded.rate}, "
              "its last complete layer [§3.8.4]", file=sys.stderr)
    folder = os.path.dirname(os.path.abspath(dst))
    fd, tmp = tempfile.mkstemp(prefix=".salvq_py-", dir=folder)
    os.close(fd)
    try:
        write_safetensors(tmp, form, {"format": "salvq-decoded"})
        os.replace(tmp, dst)
    except OSError as e:
        os.unlink(tmp)
        print(f"salvq_py: error[Io]: {e}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
