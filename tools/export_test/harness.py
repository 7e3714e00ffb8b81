"""What the test's modules share: the repository's paths, the pass/fail record, running a
command, and the per-tensor table row."""
from __future__ import annotations

import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent.parent
EXPORTER = ROOT / "tools" / "export_checkpoint.py"

RESULTS: list[tuple[str, bool, str]] = []


def check(name: str, ok: bool, detail: str = ""):
    RESULTS.append((name, bool(ok), detail))
    print(f"  {'ok  ' if ok else 'FAIL'} {name}" + (f": {detail}" if detail else ""), flush=True)


def run(cmd, **kw):
    r = subprocess.run([str(c) for c in cmd], capture_output=True, text=True, **kw)
    return r


def table_row(name, err, bound, ok):
    print(f"    {name:<28} max|err| {err:11.4g}   bound {bound if isinstance(bound, str) else f'{bound:11.4g}'}"
          f"   {'ok' if ok else 'FAIL'}")
