"""The command line of tools/export_checkpoint.py: options, the printed summary, the --json
report, and the error line and exit status 2 for a checkpoint that cannot be mapped."""
from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from .common import ExportError
from .export import export
from .model import write_safetensors

DESCRIPTION = "Export a HAC or SALVQ training output (the public PyTorch code) to a salvq model file."


def summary(rep: dict) -> str:
    d = rep["dims"]
    lines = [
        f"format {rep['format']} ({rep['state']} state); {rep['anchors']['exported']} anchors "
        f"exported of {rep['anchors']['in_ply']} in the PLY "
        f"({rep['anchors']['with_empty_mask']} with an all-zero mask)",
        "dims: " + ", ".join(f"{k_}={v_}" for k_, v_ in d.items()),
        f"voxel size {rep['voxels']['voxel_size']:g} ({rep['voxels']['source']}), origin "
        f"{[round(x, 6) for x in rep['voxels']['origin']]}, coord_bits {rep['voxels']['coord_bits']}, "
        f"largest position change {rep['voxels']['max_position_change']:.3g}",
        f"HAC box {[round(x, 6) for x in rep['x_bound']['min']]} .. "
        f"{[round(x, 6) for x in rep['x_bound']['max']]} ({rep['x_bound']['source']})",
    ]
    g = rep["grid"]
    res3 = [lv["resolution"] for lv in g["levels"] if lv["plane"] == "3d"]
    res2 = [lv["resolution"] for lv in g["levels"] if lv["plane"] == "xy"]
    lines.append(f"hash grid ({g['mode']} resolutions): 3D {res3}, 2D {res2}, log2 {g['log2_size']}; "
                 f"mean |HAC feature - ours| at the anchors {g['mean_abs_feature_difference']:.3f}, "
                 f"same sign {100 * g['sign_agreement']:.1f} %")
    bh, bo = rep["estimated_bits_hac_context"], rep["estimated_bits_mapped_context"]
    parts = []
    for key in ("feat", "scaling", "offsets"):
        if bh[key] == bh[key] and bh[key] > 0:
            parts.append(f"{key} {bh[key] / 8:.0f} -> {bo[key] / 8:.0f} B ({100 * (bo[key] / bh[key] - 1):+.1f} %)")
    if parts:
        lines.append("HAC's float estimate of the symbol bytes, its own grid context -> the mapped "
                     "grid: " + ", ".join(parts))
    if "salvq" in rep:
        s = rep["salvq"]
        lines.append(f"SALVQ basis: |U^T U - I| {s['orthogonality_U']:.1e}, |V^T V - I| "
                     f"{s['orthogonality_V']:.1e}, gain {s['gain_min']:.4g} .. {s['gain_max']:.4g} "
                     f"(condition {s['condition']:.3g})")
    for nt in rep["notes"]:
        lines.append("note: " + nt)
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=DESCRIPTION,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("run_dir", type=Path, help="run folder (model_path) or one iteration folder")
    ap.add_argument("-o", "--output", type=Path, required=True, help="output model (safetensors)")
    ap.add_argument("--format", choices=("auto", "hac", "salvq"), default="auto",
                    help="auto: salvq when the checkpoint has mlp_U, mlp_V and gain")
    ap.add_argument("--iteration", type=int, help="point_cloud/iteration_<N> (default: the largest)")
    ap.add_argument("--ply", type=Path, help="anchor PLY (default: <iteration>/point_cloud.ply)")
    ap.add_argument("--checkpoint", type=Path, help="MLP checkpoint (default: <iteration>/checkpoint.pth)")
    ap.add_argument("--state", choices=("auto", "raw", "decoded"), default="auto",
                    help="raw: PLY holds mask logits and log-scales; decoded: HAC's codec ran "
                         "before saving (run_codec=True, the default) (A.7.2)")
    ap.add_argument("--voxel-size", type=float, help="default: cfg_args voxel_size, else inferred")
    ap.add_argument("--snap", action="store_true", help="round off-grid anchors to the voxel grid")
    ap.add_argument("--x-bound-min", help="HAC's x_bound_min x,y,z (default: recomputed); "
                    "write --x-bound-min=-1.2,0.5,3 when it starts with a minus")
    ap.add_argument("--x-bound-max", help="HAC's x_bound_max x,y,z (default: recomputed)")
    ap.add_argument("--grid-resolutions", choices=("matched", "hac"), default="matched",
                    help="matched: our level resolutions give HAC's world-space vertex spacing; "
                         "hac: HAC's numbers verbatim (A.7.4)")
    ap.add_argument("--gains", default="1", help="per-rate gains, e.g. 1,1.5,2 (default 1)")
    ap.add_argument("--drop-empty-anchors", action="store_true",
                    help="drop anchors whose masks are all zero (as HAC's codec does)")
    ap.add_argument("--json", type=Path, help="also write the report as JSON")
    args = ap.parse_args(argv)
    try:
        try:
            gains = [float(x) for x in args.gains.split(",")]
        except ValueError:
            raise ExportError(f"--gains {args.gains!r}: not a list of numbers") from None
        if not gains or not all(math.isfinite(x) and x > 0 for x in gains) or len(gains) > 64:
            raise ExportError("--gains: 1 to 64 finite values > 0 [§2.3]")
        rep = export(args)
        nbytes = write_safetensors(args.output, rep["tensors"], rep["lattice"])
    except ExportError as e:
        print(f"export_checkpoint: error: {e}", file=sys.stderr)
        return 2
    print(summary(rep))
    print(f"wrote {args.output} ({nbytes} bytes, feat lattice {rep['lattice']})")
    if args.json:
        out = {k_: v_ for k_, v_ in rep.items() if k_ != "tensors"}
        args.json.write_text(json.dumps(out, indent=1))
    return 0

