"""Export a HAC or SALVQ training output (the public PyTorch code) to a salvq model file.

The code behind tools/export_checkpoint.py (its command line: tools/README.md; the mapping:
spec Annex A.7), one module per concern, in the order the export runs:

- run_folder.py  where point_cloud.ply, checkpoint.pth and cfg_args are (A.7.1)
- checkpoint.py  checkpoint.pth: format, MLPs (A.7.5), SALVQ's orthogonal basis and gain (A.7.6)
- ply.py         the anchor PLY, raw vs decoded state (A.7.2)
- voxels.py      voxel size, voxel grid, HAC's 16-bit positions and box (A.7.3, A.7.4)
- grid.py        HAC's hash grids resampled onto ours (A.7.4)
- estimate.py    HAC's float estimate of the coded bits (what the grid mapping costs)
- model.py       §2.3 value checks and the byte-canonical safetensors writer (A.1)
- export.py      the steps above in order, and the report
- cli.py         options, summary, --json, error line and exit status
- common.py      HAC's constants used in several modules, ExportError

The code cites the public code it follows as `HAC:<path>:<function>`
(github.com/YihangChen-ee/HAC) and `SALVQ:<path>:<function>` (github.com/hxu160/SALVQ, a
fork of HAC that adds mlp_U, mlp_V and Gain). Only numpy is imported at module level; torch
is imported where it is used.
"""
from .cli import main, summary
from .common import SCHEMA, ExportError
from .export import export
from .model import validate, write_safetensors

__all__ = ["ExportError", "SCHEMA", "export", "main", "summary", "validate", "write_safetensors"]
