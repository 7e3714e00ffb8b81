"""checkpoint.pth (A.7.1, A.7.5, A.7.6): the dict of state dicts, the format it is, the
Scaffold-GS and context MLPs, and SALVQ's orthogonal parametrizations and gain."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .common import ExportError


def load_checkpoint(path: Path) -> dict:
    import torch
    try:
        # weights_only: a state dict is tensors in dicts; nothing in it is executed.
        ck = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as e:  # noqa: BLE001 - any unpickling failure is the user's file
        raise ExportError(f"{path}: torch.load failed ({type(e).__name__}: {e}) [A.7.1]") from None
    if not isinstance(ck, dict):
        raise ExportError(f"{path}: not a dict of state dicts (HAC:save_mlp_checkpoints) [A.7.1]")
    return ck


def f32(t) -> np.ndarray:
    import torch
    return t.detach().cpu().to(dtype=torch.float32).numpy().copy()


def orthogonal_weight(sd: dict, f: int, key: str) -> np.ndarray:
    """The weight SALVQ uses: SALVQ:scene/gaussian_model.py registers
    P.orthogonal(nn.Linear(feat_dim, feat_dim, bias=False)); its state dict holds
    parametrizations.weight.original and parametrizations.weight.0.base. Loading it into the
    same module and reading .weight runs PyTorch's own map (base @ matrix_exp(A)), so the
    matrix is the one training used (up to CPU vs GPU rounding). A plain 'weight' (a model
    whose parametrization was removed) is taken as it is."""
    import torch
    import torch.nn as nn
    import torch.nn.utils.parametrizations as P
    if "weight" in sd and not any(k.startswith("parametrizations.") for k in sd):
        w = f32(sd["weight"])
    else:
        m = P.orthogonal(nn.Linear(f, f, bias=False))
        try:
            m.load_state_dict(sd)
        except Exception as e:  # noqa: BLE001
            raise ExportError(f"checkpoint['{key}']: not the state dict of "
                              f"P.orthogonal(nn.Linear({f}, {f}, bias=False)) ({e}) [A.7.6]") from None
        with torch.no_grad():
            w = f32(m.weight)
    if w.shape != (f, f):
        raise ExportError(f"checkpoint['{key}']: weight {w.shape}, expected ({f}, {f}) [A.7.6]")
    err = float(np.abs(w.astype(np.float64) @ w.T.astype(np.float64) - np.eye(f)).max())
    if err > 1e-3:
        raise ExportError(f"checkpoint['{key}']: weight is not orthogonal (|W W^T - I| = {err:.2e} "
                          "> 1e-3, spec §2.6 BasisNotOrthogonal) [A.7.6]")
    return w


def salvq_basis(ck: dict, f: int, t: dict):
    """A.7.6. SALVQ decodes x = ((Q u) W_U / g) W_V + mu (row vectors;
    SALVQ:scene/gaussian_model.py:conduct_decoding, gaussian_renderer/__init__.py), that is
    x = mu + Q (W_V^T diag(1/g) W_U^T) u, so B = U diag(s) V^T with U = W_V^T, s = 1/g, V = W_U.
    Fills the basis tensors of t; returns (W_U, g, W_V) and a report."""
    wu = orthogonal_weight(ck["mlp_U"], f, "mlp_U")
    wv = orthogonal_weight(ck["mlp_V"], f, "mlp_V")
    g = f32(ck["gain"]).reshape(-1)
    if g.shape != (f,):
        raise ExportError(f"checkpoint['gain']: shape {tuple(ck['gain'].shape)}, "
                          f"expected [1, {f}] [A.7.6]")
    if (g == 0).any() or not np.isfinite(g).all():
        raise ExportError("checkpoint['gain']: a zero or non-finite gain (s = 1/gain) [A.7.6]")
    t["quant.feat.basis_u"] = np.ascontiguousarray(wv.T).astype(np.float32)
    t["quant.feat.basis_s"] = (1.0 / g.astype(np.float64)).astype(np.float32)
    t["quant.feat.basis_v"] = np.ascontiguousarray(wu).astype(np.float32)
    rep = {"orthogonality_U": float(np.abs(wv.astype(np.float64).T @ wv - np.eye(f)).max()),
           "orthogonality_V": float(np.abs(wu.astype(np.float64).T @ wu - np.eye(f)).max()),
           "gain_min": float(np.abs(g).min()), "gain_max": float(np.abs(g).max()),
           "condition": float(np.abs(g).max() / np.abs(g).min())}
    return (wu, g, wv), rep


def checkpoint_format(ck: dict, ckpt_path: Path, cfg: dict, fmt_opt: str, note) -> str:
    """`--format auto|hac|salvq` against what the checkpoint holds (A.7.1), the keys every
    HAC checkpoint has, and the feature bank that has no tensor in the format (A.7.7)."""
    # -- format (A.7.1): SALVQ:scene/gaussian_model.py:save_mlp_checkpoints adds mlp_U, mlp_V, gain.
    is_salvq = all(k in ck for k in ("mlp_U", "mlp_V", "gain"))
    fmt = fmt_opt
    if fmt == "auto":
        fmt = "salvq" if is_salvq else "hac"
    if fmt == "salvq" and not is_salvq:
        raise ExportError("--format salvq: the checkpoint has no mlp_U / mlp_V / gain [A.7.1]")
    if fmt == "hac" and is_salvq:
        note("the checkpoint is SALVQ's; --format hac exports it as USQ, ignoring mlp_U, mlp_V, gain")
    for key in ("opacity_mlp", "cov_mlp", "color_mlp", "encoding_xyz", "grid_mlp"):
        if key not in ck:
            raise ExportError(f"{ckpt_path}: no '{key}' (HAC:save_mlp_checkpoints keys) [A.7.1]")
    if "mlp_feature_bank" in ck or cfg.get("use_feat_bank"):
        raise ExportError("use_feat_bank=True: the view-dependent feature bank (mlp_feature_bank) "
                          "has no tensor in the format [A.7.7]")
    return fmt


def read_mlps(ck: dict, f: int, k: int, s_dim: int, cin: int, note):
    """The context MLP and the three Scaffold-GS MLPs (A.7.5) as our tensors, their shapes
    checked against F, K, S and Cin. Returns (tensors, H, Hs, V, Cout)."""
    # -- MLPs (A.7.5): HAC:GaussianModel.__init__ nn.Sequential(Linear, ReLU, Linear[, act]).
    t = {}
    pairs = [("grid_mlp", "mlp_grid"), ("opacity_mlp", "mlp_opacity"), ("cov_mlp", "mlp_cov"),
             ("color_mlp", "mlp_color")]
    for src, dst in pairs:
        sd = ck[src]
        for key in ("0.weight", "0.bias", "2.weight", "2.bias"):
            if key not in sd:
                raise ExportError(f"checkpoint['{src}'] has no '{key}' (keys {sorted(sd)}) [A.7.5]")
            t[f"{dst}.{key}"] = f32(sd[key])
        extra = sorted(set(sd) - {"0.weight", "0.bias", "2.weight", "2.bias"})
        if extra:
            raise ExportError(f"checkpoint['{src}'] has layers beyond Linear-ReLU-Linear: {extra} [A.7.5]")
    h = t["mlp_grid.0.weight"].shape[0]
    cout = 2 * (f + s_dim + 3 * k) + 3
    hs, fin = t["mlp_opacity.0.weight"].shape
    vdim = fin - f
    want = {
        "mlp_grid.0.weight": (h, cin), "mlp_grid.0.bias": (h,), "mlp_grid.2.weight": (cout, h),
        "mlp_grid.2.bias": (cout,),
        "mlp_opacity.0.weight": (hs, f + vdim), "mlp_opacity.0.bias": (hs,),
        "mlp_opacity.2.weight": (k, hs), "mlp_opacity.2.bias": (k,),
        "mlp_cov.0.weight": (hs, f + vdim), "mlp_cov.0.bias": (hs,),
        "mlp_cov.2.weight": (7 * k, hs), "mlp_cov.2.bias": (7 * k,),
        "mlp_color.0.weight": (hs, f + vdim), "mlp_color.0.bias": (hs,),
        "mlp_color.2.weight": (3 * k, hs), "mlp_color.2.bias": (3 * k,),
    }
    for name, shp in want.items():
        if t[name].shape != shp:
            raise ExportError(f"{name}: shape {t[name].shape}, expected {shp} for F={f}, K={k}, "
                              f"S={s_dim}, Cin={cin} [A.7.5]")
    if s_dim != 6:
        note(f"{s_dim} scaling dimensions (HAC has 6)")
    if vdim < 0 or vdim > 8:
        raise ExportError(f"Scaffold-GS MLP input {fin} - F = {vdim} view inputs (0..8) [A.7.5]")
    if "deform_mlp" in ck:
        note("deform_mlp is saved but never used for rendering or coding (HAC excludes it from "
             "get_mlp_size); not exported")
    return t, h, hs, vdim, cout
