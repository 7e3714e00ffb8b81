"""Command line, §11.5 contract:  python3 -m salvq_py IN OUT RATE

Writes the canonical form (§11.1; §11.6 for an explicit-profile stream) of IN decoded at RATE
to OUT as safetensors and exits 0; on a stream error prints `salvq_py: error[CLASS]: message`
to stderr and exits 1."""
from __future__ import annotations

import os
import sys
import tempfile

from . import decode_canonical
from .canonical import write_safetensors
from .errors import SalvqError


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if len(argv) not in (2, 3) or argv[0] in ("-h", "--help"):
        print("usage: python3 -m salvq_py IN OUT [RATE]", file=sys.stderr)
        return 2
    src, dst = argv[0], argv[1]
    rate = int(argv[2]) if len(argv) == 3 else None
    try:
        form = decode_canonical(src, rate)
    except SalvqError as e:
        print(f"salvq_py: error[{e.error_class}]: {e.message}", file=sys.stderr)
        return 1
    except OSError as e:
        print(f"salvq_py: error[Io]: {e}", file=sys.stderr)
        return 1
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
