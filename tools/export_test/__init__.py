"""The pieces of tools/test_export_checkpoint.py, the exporter's end-to-end test (spec Annex
A.7). They import nothing from salvq_export/: the training outputs, the §5 reading of the
stream and HAC's grid lookup are written here independently of the exporter and the encoder.

- training_output.py  HAC / SALVQ training outputs as the public code writes them
- stream.py           spec §5 from the decoded model and the stream (MLPS, grid features, steps)
- hac_grid.py         HAC's gridencoder.cu lookup in torch
- checks.py           one decoded model against the checkpoint (every tensor, its bound)
- cases.py            one case end to end, or one expected error
- harness.py          paths, the pass/fail record, running a command, table rows
"""
