"""The training run's files: where point_cloud.ply, checkpoint.pth and cfg_args are (A.7.1)."""
from __future__ import annotations

import ast
from pathlib import Path

from .common import ExportError


def locate(run_dir: Path, iteration: int | None, ply: Path | None, ckpt: Path | None):
    """Find point_cloud.ply, checkpoint.pth and cfg_args as HAC:scene/__init__.py:Scene.save
    writes them: <model_path>/point_cloud/iteration_<N>/{point_cloud.ply, checkpoint.pth}, and
    <model_path>/cfg_args (HAC:train.py:prepare_output_and_logger)."""
    run_dir = Path(run_dir)
    if (run_dir / "point_cloud.ply").exists() or (run_dir / "checkpoint.pth").exists():
        it_dir, model_path = run_dir, run_dir.parent.parent
    else:
        pc = run_dir / "point_cloud"
        if not pc.is_dir():
            raise ExportError(f"{run_dir}: neither an iteration folder (point_cloud.ply, "
                              "checkpoint.pth) nor a run folder with point_cloud/ [A.7.1]")
        iters = []
        for p in pc.iterdir():
            if p.name.startswith("iteration_") and p.name[10:].isdigit():
                iters.append(int(p.name[10:]))
        if iteration is None:
            if not iters:
                raise ExportError(f"{pc}: no iteration_<N> folder [A.7.1]")
            # HAC:utils/system_utils.py:searchForMaxIteration: the largest N.
            iteration = max(iters)
        it_dir, model_path = pc / f"iteration_{iteration}", run_dir
        if not it_dir.is_dir():
            raise ExportError(f"{it_dir}: no such iteration (have {sorted(iters)}) [A.7.1]")
    ply = Path(ply) if ply else it_dir / "point_cloud.ply"
    ckpt = Path(ckpt) if ckpt else it_dir / "checkpoint.pth"
    for p in (ply, ckpt):
        if not p.is_file():
            raise ExportError(f"{p}: missing [A.7.1]")
    cfg = model_path / "cfg_args"
    return ply, ckpt, (cfg if cfg.is_file() else None)


def read_cfg_args(path: Path | None) -> dict:
    """cfg_args is `str(Namespace(**vars(args)))` (HAC:train.py:prepare_output_and_logger);
    parsed with ast (literals only, nothing is executed)."""
    if path is None:
        return {}
    text = path.read_text().strip()
    try:
        node = ast.parse(text, mode="eval").body
        if not (isinstance(node, ast.Call) and getattr(node.func, "id", "") == "Namespace"):
            raise ValueError("not Namespace(...)")
        out = {}
        for kw in node.keywords:
            try:
                out[kw.arg] = ast.literal_eval(kw.value)
            except ValueError:
                pass  # a non-literal value: not one we use
        return out
    except (SyntaxError, ValueError) as e:
        raise ExportError(f"{path}: cannot parse cfg_args ({e}) [A.7.1]") from None
