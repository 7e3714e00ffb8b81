"""The anchor PLY (A.7.2): reading its `vertex` element, and the anchors it holds in the raw
or the decoded state."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .common import ExportError


PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
    "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}


def read_ply_vertices(path: Path) -> dict[str, np.ndarray]:
    """The `vertex` element of a PLY file as {property: array}. HAC writes it with plyfile
    (HAC:scene/gaussian_model.py:save_ply): binary, one f4 property per column, no lists."""
    data = path.read_bytes()
    end = data.find(b"end_header")
    if not data.startswith(b"ply") or end < 0:
        raise ExportError(f"{path}: not a PLY file [A.7.2]")
    nl = data.find(b"\n", end)
    header = data[:end].decode("ascii", "replace").splitlines()
    body = memoryview(data)[nl + 1:]
    fmt, elements = None, []
    for line in header[1:]:
        w = line.split()
        if not w or w[0] in ("comment", "obj_info"):
            continue
        if w[0] == "format":
            fmt = w[1]
        elif w[0] == "element":
            elements.append((w[1], int(w[2]), []))
        elif w[0] == "property":
            if w[1] == "list":
                raise ExportError(f"{path}: list property '{w[-1]}' not supported [A.7.2]")
            if w[1] not in PLY_TYPES or not elements:
                raise ExportError(f"{path}: bad property line '{line}' [A.7.2]")
            elements[-1][2].append((w[2], PLY_TYPES[w[1]]))
    if fmt not in ("binary_little_endian", "binary_big_endian", "ascii"):
        raise ExportError(f"{path}: unknown PLY format {fmt} [A.7.2]")
    offset = 0
    text_rows = None
    if fmt == "ascii":
        text_rows = bytes(body).decode("ascii").split("\n")
    for name, count, props in elements:
        order = "<" if fmt == "binary_little_endian" else ">"
        dt = np.dtype([(p, order + t) for p, t in props])
        if fmt == "ascii":
            rows = [r.split() for r in text_rows[offset:offset + count]]
            offset += count
            arr = np.array([tuple(r) for r in rows], dtype=[(p, t) for p, t in props]) \
                if count else np.zeros(0, dt)
        else:
            need = dt.itemsize * count
            if offset + need > len(body):
                raise ExportError(f"{path}: truncated element '{name}' [A.7.2]")
            arr = np.frombuffer(body, dtype=dt, count=count, offset=offset)
            offset += need
        if name == "vertex":
            return {p: np.ascontiguousarray(arr[p]).astype(np.float32) for p, _ in props}
    raise ExportError(f"{path}: no 'vertex' element [A.7.2]")


def columns(v: dict, prefix: str, path) -> np.ndarray:
    """Columns `prefix<i>` sorted by i, as HAC:scene/gaussian_model.py:load_ply_sparse_gaussian
    sorts them; [N, n] float32."""
    names = [k for k in v if k.startswith(prefix) and k[len(prefix):].isdigit()]
    names.sort(key=lambda s: int(s[len(prefix):]))
    if [int(s[len(prefix):]) for s in names] != list(range(len(names))):
        raise ExportError(f"{path}: properties {prefix}* are not numbered 0..n-1 [A.7.2]")
    if not names:
        return np.zeros((len(v["x"]), 0), np.float32)
    return np.stack([v[n] for n in names], axis=1).astype(np.float32)


@dataclass
class Anchors:
    """The anchors of the PLY as the format takes them: N kept of n_all, F features, K
    offsets, S scaling dimensions; mask 0/1 [N, K] u8, scaling activated [N, S]."""
    pos: np.ndarray
    feat: np.ndarray
    offsets: np.ndarray
    mask: np.ndarray
    scaling: np.ndarray
    state: str
    n_all: int
    f: int
    k: int
    s_dim: int


def read_anchors(ply: Path, state_opt: str, drop_empty: bool, note) -> Anchors:
    """The PLY's anchors (A.7.2, A.7.3): columns, the state (`--state auto|raw|decoded`),
    masks and scaling activated, and the anchors that are not anchors of the coded scene
    dropped (decoded state), or those with all-zero masks (`--drop-empty-anchors`)."""
    import torch

    # -- PLY (A.7.2): HAC:scene/gaussian_model.py:save_ply / construct_list_of_attributes.
    v = read_ply_vertices(ply)
    for c in ("x", "y", "z"):
        if c not in v:
            raise ExportError(f"{ply}: no property {c} [A.7.2]")
    pos = np.stack([v["x"], v["y"], v["z"]], axis=1).astype(np.float32)
    feat = columns(v, "f_anchor_feat_", ply)
    off_flat = columns(v, "f_offset_", ply)
    mask_raw = columns(v, "f_mask_", ply)
    scale_raw = columns(v, "scale_", ply)
    n_all, f = feat.shape
    k = mask_raw.shape[1]
    s_dim = scale_raw.shape[1]
    if f == 0 or k == 0 or s_dim == 0:
        raise ExportError(f"{ply}: needs f_anchor_feat_*, f_mask_* and scale_* properties [A.7.2]")
    if off_flat.shape[1] != 3 * k:
        raise ExportError(f"{ply}: {off_flat.shape[1]} f_offset_* for {k} f_mask_* (want 3K) [A.7.2]")
    # save_ply writes _offset [N, K, 3] as transpose(1, 2).flatten: column c*K + k is
    # coordinate c of offset k (load_ply_sparse_gaussian reshapes (N, 3, K), transposes back).
    offsets = off_flat.reshape(n_all, 3, k).transpose(0, 2, 1).copy()
    for name, arr in (("position", pos), ("f_anchor_feat", feat), ("f_offset", off_flat),
                      ("f_mask", mask_raw), ("scale", scale_raw)):
        if not np.isfinite(arr).all():
            i = int(np.argwhere(~np.isfinite(arr))[0][0])
            raise ExportError(f"{ply}: anchor {i}: {name} is not finite [A.7.2]")

    # Columns Scaffold-GS rendering does not read (HAC:gaussian_renderer/__init__.py:
    # generate_neural_gaussians uses anchor, feat, offsets, scaling, masks; prefilter_voxel
    # culls with the anchor's scaling and rotation, which stays the identity it is created with).
    rot = columns(v, "rot_", ply)
    ident = float((np.abs(rot - np.array([1, 0, 0, 0], np.float32)).max(axis=1) < 1e-6).mean()) \
        if rot.shape[1] == 4 else float("nan")
    note("not exported (no tensor in the format, not used to render): nx ny nz, opacity, rot_* "
         f"({100 * ident:.1f} % of the rotations are the identity)")

    # -- state (A.7.2): HAC:train.py calls training_report (which, with run_codec = True, runs
    # conduct_encoding + conduct_decoding and sets decoded_version) before scene.save at the
    # last test iteration, so the default run saves the *decoded* model.
    binary_masks = bool(np.isin(mask_raw, (0.0, 1.0)).all())
    state = state_opt
    if state == "auto":
        if not binary_masks or (scale_raw < 0).any():
            state = "raw"
        else:
            state = "decoded"
            note("state auto -> decoded: masks are all 0/1 and no scale is negative (a raw "
                 "model stores mask logits and log-scales); pass --state raw to override")
    if state == "decoded" and not binary_masks:
        raise ExportError("--state decoded: f_mask_* values other than 0 and 1 [A.7.2]")
    if state == "raw":
        # HAC:GaussianModel.get_mask: sigmoid(_mask) > 0.01; get_scaling: exp(_scaling).
        mask = (torch.sigmoid(torch.from_numpy(mask_raw)) > 0.01).numpy().astype(np.uint8)
        scaling = torch.exp(torch.from_numpy(scale_raw)).numpy().astype(np.float32)
    else:
        # decoded_version: _mask holds 0/1, _scaling the (decoded) activated scaling.
        mask = mask_raw.astype(np.uint8)
        scaling = scale_raw.astype(np.float32)
    if not np.isfinite(scaling).all():
        raise ExportError("exp(scale_*) overflows binary32 [A.7.2]")

    keep = np.ones(n_all, bool)
    empty = mask.sum(axis=1) == 0
    if state == "decoded":
        # conduct_decoding fills anchors n .. N_full-1 (those whose masks were all 0, which
        # conduct_encoding dropped) with zeros: they are not anchors of the coded scene.
        keep &= ~empty
        if empty.any():
            note(f"dropped {int(empty.sum())} zero-filled anchors (all-zero mask) that HAC's "
                 "conduct_decoding appends")
    elif drop_empty:
        keep &= ~empty
        note(f"--drop-empty-anchors: dropped {int(empty.sum())} anchors with an all-zero mask "
             "(HAC:conduct_encoding drops them too; they spawn no Gaussian)")
    if not keep.any():
        raise ExportError("no anchor left (every mask is all zero) [A.7.2]")
    pos, feat, offsets, mask, scaling = pos[keep], feat[keep], offsets[keep], mask[keep], scaling[keep]
    return Anchors(pos=pos, feat=feat, offsets=offsets, mask=mask, scaling=scaling, state=state,
                   n_all=n_all, f=f, k=k, s_dim=s_dim)
