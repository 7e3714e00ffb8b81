#!/usr/bin/env python3
"""Export a HAC or SALVQ training output (the public PyTorch code) to a salvq model file.

Usage (see tools/README.md, "Exporting HAC / SALVQ checkpoints"):

    python3 tools/export_checkpoint.py RUN_DIR -o model.safetensors [--format auto|hac|salvq]
        [--iteration N] [--state auto|raw|decoded] [--voxel-size V]
        [--x-bound-min X,Y,Z --x-bound-max X,Y,Z] [--grid-resolutions matched|hac]
        [--gains G0,G1,...] [--drop-empty-anchors] [--json REPORT.json]

RUN_DIR is the training run's `model_path` (holding `cfg_args` and
`point_cloud/iteration_<N>/{point_cloud.ply,checkpoint.pth}`) or one iteration folder.
The output is the safetensors model of spec Annex A (schema 0.2), written byte-canonically
(A.1), which `salvq encode` reads. The mapping, every transform and every gap between the
two formats is spec Annex A.7. This file is the entry point; the code is the package
tools/salvq_export/ (one module per concern, listed in its __init__.py), which cites the public
code it follows as `HAC:<path>:<function>` (github.com/YihangChen-ee/HAC) and
`SALVQ:<path>:<function>` (github.com/hxu160/SALVQ, a fork of HAC that adds mlp_U, mlp_V and
Gain).

Needs Python >= 3.10, numpy and torch (CPU is enough; only `torch.load`, the orthogonal
parametrization and a few float64 matrix products are used). Nothing else is imported.

Exit status: 0 on success; 2 with one line `export_checkpoint: error: ...` on stderr when the
checkpoint cannot be mapped (the message names the rule of Annex A.7 that fails).
"""
from __future__ import annotations

import sys
from pathlib import Path

_TOOLS = str(Path(__file__).resolve().parent)
if _TOOLS not in sys.path:  # also when this file is imported, or run from another folder
    sys.path.insert(0, _TOOLS)

from salvq_export import (SCHEMA, ExportError, export, main, summary,  # noqa: E402
                          validate, write_safetensors)

# What this file defined before the code moved to salvq_export/, importable from here as before.
__all__ = ["SCHEMA", "ExportError", "export", "main", "summary", "validate", "write_safetensors"]

if __name__ == "__main__":
    sys.exit(main())
