"""One test case: make a training output, export it, encode, decode, read `salvq info`, and
check the result; or expect the exporter to refuse it with a clear error."""
from __future__ import annotations

import json
import sys
from pathlib import Path

from safetensors.numpy import load_file

from .checks import compare
from .harness import EXPORTER, check, run
from .training_output import make_run


def run_case(name, work: Path, salvq_bin: Path, *, salvq, decoded, use_2d, n, seed,
             export_args=(), encode_args=(), grid_check=True, **kw):
    print(f"\n== case {name}")
    run_dir = work / name
    truth = make_run(run_dir, salvq=salvq, decoded=decoded, use_2d=use_2d, n_target=n, seed=seed, **kw)
    model_path = work / f"{name}.safetensors"
    rep_path = work / f"{name}.json"
    r = run([sys.executable, EXPORTER, run_dir, "-o", model_path, "--json", rep_path, *export_args])
    print("\n".join("    | " + ln for ln in r.stdout.strip().splitlines()))
    check(f"{name}: exporter exits 0", r.returncode == 0, r.stderr.strip() if r.returncode else "")
    if r.returncode != 0:
        return None
    rep = json.loads(rep_path.read_text())
    exp = load_file(str(model_path))
    bytes_out = {}
    for search in (["auto"] + (["rounding"] if salvq else [])):
        stream_path = work / f"{name}.{search}.salvq"
        dec_path = work / f"{name}.{search}.decoded.safetensors"
        r = run([salvq_bin, "encode", model_path, "-o", stream_path, "--quantizer", "model",
                 "--search", search, *encode_args])
        check(f"{name}: salvq encode --search {search}", r.returncode == 0,
              r.stderr.strip()[-400:] if r.returncode else "")
        if r.returncode != 0:
            return None
        r = run([salvq_bin, "decode", stream_path, "-o", dec_path])
        check(f"{name}: salvq decode", r.returncode == 0, r.stderr.strip()[-400:])
        if r.returncode != 0:
            return None
        info = json.loads(run([salvq_bin, "info", stream_path, "--json"]).stdout)
        dec = load_file(str(dec_path))
        stream = stream_path.read_bytes()
        bytes_out[search] = info["totals"]
        compare(f"{name} [{search}]", truth, exp, dec, info, stream, salvq=salvq,
                rigorous_lattice=(search == "rounding" or not salvq), decoded_state=decoded,
                use_2d=use_2d, rep=rep, grid_check=grid_check and search == "auto")
        if search == "auto":
            t = info["totals"]
            print(f"    end to end: {t['file_bytes']} bytes = model {t['model_bytes']} + anchors "
                  f"{t['anchor_bytes']} + other {t['other_bytes']}; {t['bits_per_anchor']:.1f} bits/anchor "
                  f"({info['head']['anchors']} anchors)")
    return bytes_out


def expect_error(name, work, salvq_bin, needle, mutate, **kw):
    run_dir = work / name
    truth = make_run(run_dir, **kw)
    args = mutate(run_dir, truth) or []
    r = run([sys.executable, EXPORTER, run_dir, "-o", work / f"{name}.safetensors", *args])
    ok = r.returncode == 2 and needle in r.stderr and not (work / f"{name}.safetensors").exists()
    check(f"{name}: clear error", ok, r.stderr.strip() if ok else f"rc {r.returncode}: {r.stderr.strip()[-300:]}")
