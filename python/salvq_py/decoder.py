"""The decoding processes: chunk order and per-chunk decoding of the anchors profile (§1.5,
§7.4 rate selection) and of the explicit-Gaussians profile (§3.7; its progressive streams,
§3.8, since 0.15), told apart by the first chunk (§1.5)."""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .container import Chunk, Limits, check_signature, read_chunk
from .entropy import Prior, decode_amsk, decode_layer, payload_method
from .errors import SalvqError
from .explicit import GHead, parse_ghed, parse_glay, parse_gqua, parse_gref
from .gatt import decode_gatt
from .grsy import Precision, decode_grsy
from .gaussians import reconstruct_gaussians
from .geometry import decode_apos
from .hyperprior import (grid_body_length, mlp_grid_tensors, parse_grid,
                         parse_mlps, touched_entries)
from .model import Dims, parse_head
from .quantizers import parse_quan, quan_body_length
from .region import parse_region, rebase, select_tiles, selected_rows
from .tiles import check_tiles, parse_tils, split_tiles

KNOWN_CRITICAL = ("HEAD", "MLPS", "QUAN", "TILS", "APOS", "GRID", "AMSK", "AFEA", "ASCL",
                  "AOFF", "SEND")                                     # Table 1-3
EXPLICIT_CRITICAL = ("GHED", "GQUA", "GLAY", "TILS", "APOS", "GATT", "GREF", "GRSY",
                     "SEND")                                                    # Table 3-2


@dataclass
class Decoded:
    """An anchors-profile decode."""
    dims: Dims
    rate: int
    tensors: dict          # Table 2-1 tensors (present ones), numpy arrays
    symbols: dict          # feat [N, F], scaling [N, S], offsets [N, K, 3], int64
    profile = "anchors"
    tiles: list | None = None   # region decode (§10.3.1): the selected tiles' indices


@dataclass
class ExplicitDecoded:
    """An explicit-profile decode (§3): the selected layer's Gaussians."""
    head: GHead
    rate: int
    integers: dict         # Table 11-2, in order
    tensors: dict          # Table 3-4 (the decoded Gaussians), in order
    profile = "explicit"
    tiles: list | None = None   # region decode (§10.3.1): the selected tiles' indices
    prefix: bool = False   # §3.8.4: a progressive stream that ended early, decoded to `rate`


def _fixed_length(tag: str, payload: bytes, method: int, body_len: int) -> bytes:
    """§1.6 steps 1-3 for a chunk whose body length is known."""
    payload_method(tag, payload, method)
    if len(payload) != 1 + body_len:
        raise SalvqError("ChunkSizeMismatch",
                         f"chunk {tag}: payload length {len(payload)}, expected {1 + body_len} [§1.6]")
    return payload[1:]


def _select_rate(rate: int | None, M: int, rate_mask: int) -> int:
    """The selected rate (§1.5, §3.2 step 7): by default the lowest coded one."""
    if rate is None:
        rate = next(r for r in range(64) if (rate_mask >> r) & 1)
    if rate >= M:
        raise SalvqError("FieldOutOfRange", f"field rate = {rate}, range 0 … {M - 1} [§1.5]")
    if not (rate_mask >> rate) & 1:
        raise SalvqError("RateNotCoded", f"rate {rate} has no layer in the stream [§7.4]")
    return rate


def _send(chunk: Chunk, data: bytes, pos: int) -> None:
    """§1.5 rules 4-5: SEND is empty and last."""
    if len(chunk.payload) != 0:
        raise SalvqError("ChunkSizeMismatch",
                         f"chunk SEND: payload length {len(chunk.payload)}, expected 0 [§1.5]")
    if pos != len(data):
        raise SalvqError("TrailingData", f"{len(data) - pos} bytes after SEND [§1.5]")


def decode_bytes(data: bytes, rate: int | None = None, limits: Limits | None = None,
                 region=None, prefix: bool = False):
    """Decode a stream of either profile: a `Decoded` (anchors) or an `ExplicitDecoded`.
    `region` (six numbers or the string `x0,y0,z0,x1,y1,z1`) makes it a region decode
    (§10.3.1); a box that is no box raises `region.RegionError` before the stream is read.
    `prefix` consents to decoding a progressive stream that ends early (§3.8.4) to its last
    complete layer; without it the truncation is the error."""
    box = None if region is None else parse_region(region)
    limits = limits or Limits()
    pos = check_signature(data)
    first, pos = read_chunk(data, pos, limits)
    if first.tag == "GHED":                                            # §1.5, §3
        return _decode_explicit(data, first, pos, rate, limits, box, prefix)
    return _decode_anchors(data, first, pos, rate, limits, box)


def _decode_explicit(data: bytes, chunk: Chunk, pos: int, rate: int | None,
                     limits: Limits, box=None, prefix: bool = False) -> ExplicitDecoded:
    """§3.7: GHED GQUA (GLAY TILS APOS GATT)×L SEND; the selected layer's chunks are decoded
    as they are read, the other layers' are only checked as chunks and for their order. A
    progressive stream (§3.8): GHED GQUA GLAY TILS APOS GATT (GREF GRSY)×(L − 1) SEND, layers
    in decreasing rate order; the full layer and every refinement up to the selected rate's
    are decoded as they are read. With `prefix` (the caller's consent, §3.8.4) a progressive
    stream that ends before SEND after its full layer's GATT decodes to the last layer whose
    chunks are all present (the result's `prefix` is True and its `rate` names that layer)."""
    order = ["GHED"]
    due = 0
    layer = -1
    sel = None
    progressive = False
    complete = -1               # progressive: the last layer whose chunks are all decoded
    cut = False
    while True:
        tag = chunk.tag
        if chunk.critical and tag not in EXPLICIT_CRITICAL:
            raise SalvqError("UnknownCriticalChunk",
                             f"chunk {tag}: unknown critical chunk of the explicit profile [§3.7]")
        if chunk.critical:
            if tag != order[due]:
                raise SalvqError("ChunkOrder", f"chunk {tag}: expected {order[due]} [§3.7]")
            due += 1
            p = chunk.payload
            if tag == "GHED":
                head = parse_ghed(p, limits)                           # §3.2 steps 1-6
                rate = _select_rate(rate, head.M, head.rate_mask)      # §3.2 step 7
                coded = head.layer_rates()                             # rate of each layer
                progressive = head.progressive
                if progressive:                                        # §3.7, §3.8
                    order = (["GHED", "GQUA", "GLAY", "TILS", "APOS", "GATT"]
                             + ["GREF", "GRSY"] * (len(coded) - 1) + ["SEND"])
                    last = coded.index(rate)                           # the selected layer
                else:
                    order = ["GHED", "GQUA"] + ["GLAY", "TILS", "APOS", "GATT"] * len(coded) + ["SEND"]
            elif tag == "GQUA":
                groups = parse_gqua(p, head)
            elif tag == "SEND":
                _send(chunk, data, pos)
                break
            elif progressive:
                if tag in ("GLAY", "GREF"):
                    layer += 1
                if layer <= last:                                      # up to the selected layer
                    if tag == "GLAY":
                        lay = parse_glay(p, head)
                    elif tag == "TILS":
                        payload_method(tag, p, 0)
                        tiles = parse_tils(p, head.N, lay.coord_bits)
                        sel = None if box is None else select_tiles(
                            tiles, head.origin(), lay.voxel_size, box)
                    elif tag == "APOS":
                        payload_method(tag, p, 1)
                        voxels = decode_apos(split_tiles("APOS", p, 1, len(tiles)), tiles)
                        check_tiles(tiles, voxels)
                    elif tag == "GATT":                                # the full layer, rate b
                        sym = decode_gatt(p, head, lay, tiles, voxels, sel)
                        precision = Precision.full_layer(groups, coded[0], lay)   # §3.8.3
                        complete = 0
                    elif tag == "GREF":                                # §3.8.1
                        ref = parse_gref(p, head, lay.coord_bits, precision.E)
                    else:                                              # GRSY, §3.8.2
                        sym = decode_grsy(p, head, ref, tiles, voxels, sym, sel)
                        precision = precision.refined(ref)             # §3.8.3
                        complete = layer
            else:
                if tag == "GLAY":
                    layer += 1
                if coded[layer] == rate:                               # the selected layer
                    if tag == "GLAY":
                        lay = parse_glay(p, head)
                    elif tag == "TILS":
                        payload_method(tag, p, 0)
                        tiles = parse_tils(p, head.N, lay.coord_bits)
                        # §10.3.1 steps 1-2: GHED's origin, the layer's voxel_size
                        sel = None if box is None else select_tiles(
                            tiles, head.origin(), lay.voxel_size, box)
                    elif tag == "APOS":
                        payload_method(tag, p, 1)
                        voxels = decode_apos(split_tiles("APOS", p, 1, len(tiles)), tiles)
                        check_tiles(tiles, voxels)
                    else:
                        sym = decode_gatt(p, head, lay, tiles, voxels, sel)
        try:
            chunk, pos = read_chunk(data, pos, limits)
        except SalvqError as e:                                        # §3.8.4
            if not (prefix and progressive and complete >= 0
                    and e.error_class in ("Truncated", "ChunkLengthPastEnd")):
                raise
            rate, cut = coded[complete], True
            break
    chosen = None
    if sel is not None:                                                # §10.3.1 step 4
        rows = selected_rows(tiles, sel)
        voxels, sym = voxels[rows], sym.take(rows)
        chosen = [t.index for t in tiles if sel[t.index]]
    integers = {
        "gaussian.voxel": voxels.astype(np.int32),
        "symbols.coordinates": sym.coordinates,
        "symbols.rotation_index": sym.rotation_index,
        "symbols.size_class": sym.size_class,
        "symbols.refinement": sym.refinement,
    }
    gaussians = reconstruct_gaussians(head, groups, rate, lay, voxels, sym,
                                      precision if progressive else None)
    return ExplicitDecoded(head, rate, integers, gaussians, chosen, cut)


def _decode_anchors(data: bytes, chunk: Chunk, pos: int, rate: int | None,
                    limits: Limits, box=None) -> Decoded:
    """§1.5: HEAD MLPS QUAN TILS APOS GRID AMSK (AFEA ASCL AOFF)×L SEND; the selected layer
    is decoded after SEND (§6.6.2)."""
    first = True
    dims: Dims | None = None
    order: list[str] = ["HEAD"]
    due = 0
    layer_of: list[int] = []          # rate of each layer, in stream order
    layer_index = -1
    selected = {}
    tensors: dict = {}
    while True:
        if not first:
            chunk, pos = read_chunk(data, pos, limits)
        tag = chunk.tag
        if chunk.critical and tag not in KNOWN_CRITICAL:                   # rule 0
            raise SalvqError("UnknownCriticalChunk", f"chunk {tag}: unknown critical chunk [§1.5]")
        if first and tag != "HEAD":                                        # rule 1
            raise SalvqError("ChunkOrder", f"chunk {tag} first: expected HEAD [§1.5]")
        first = False
        if not chunk.critical:                                             # rule 2
            continue
        if tag != order[due]:                                              # rule 3
            raise SalvqError("ChunkOrder", f"chunk {tag}: expected {order[due]} [§1.5]")
        due += 1
        p = chunk.payload
        if tag == "HEAD":
            dims = parse_head(p, limits)
            rate = _select_rate(rate, dims.M, dims.rate_mask)
            coded = dims.coded_rates()
            layer_of = coded
            order = (["HEAD", "MLPS", "QUAN", "TILS", "APOS", "GRID", "AMSK"]
                     + ["AFEA", "ASCL", "AOFF"] * len(coded) + ["SEND"])
            tensors["geometry.origin"] = np.array(dims.origin_bits, np.uint32).view(np.float32)
            tensors["geometry.voxel_size"] = np.array([dims.voxel_size_bits], np.uint32).view(np.float32)
            tensors["hyperprior.resolutions_3d"] = np.array(dims.res3, np.int32)
            tensors["hyperprior.resolutions_2d"] = np.array(dims.res2, np.int32)
            tensors["hyperprior.log2_size"] = np.array([dims.T3, dims.T2], np.int32)
        elif tag == "MLPS":
            payload_method(tag, p, 1)
            mlp, scaffold = parse_mlps(p, dims)
            tensors.update(mlp_grid_tensors(mlp))
            tensors.update(scaffold)
        elif tag == "QUAN":
            body = _fixed_length(tag, p, 0, quan_body_length(dims))
            groups, qt = parse_quan(body, dims)
            tensors.update(qt)
        elif tag == "TILS":
            payload_method(tag, p, 0)
            tiles = parse_tils(p, dims.N, dims.coord_bits)
            # §10.3.1 steps 1-2: HEAD's origin and voxel_size
            sel = None if box is None else select_tiles(
                tiles, tensors["geometry.origin"], tensors["geometry.voxel_size"][0], box)
        elif tag == "APOS":
            payload_method(tag, p, 1)
            bodies = split_tiles("APOS", p, 1, len(tiles))
            voxels = decode_apos(bodies, tiles)
            check_tiles(tiles, voxels)
            tensors["anchor.voxel"] = voxels.astype(np.int32)
        elif tag == "GRID":
            touched = touched_entries(dims, voxels)
            body = _fixed_length(tag, p, 1, grid_body_length(dims, touched))
            grids = parse_grid(body, dims, touched)
            tensors.update(grids)
        elif tag == "AMSK":
            mask = decode_amsk(p, dims, tiles, sel)
            tensors["anchor.mask"] = mask
        elif tag in ("AFEA", "ASCL", "AOFF"):
            if tag == "AFEA":
                layer_index += 1
            if layer_of[layer_index] == rate:
                selected[tag] = p
        elif tag == "SEND":
            _send(chunk, data, pos)                                        # rules 4-5
            break
    rows = None if sel is None else selected_rows(tiles, sel)
    prior = Prior(dims, mlp, groups, rate, voxels if rows is None else voxels[rows], grids)
    attrs, symbols = decode_layer(selected, dims, tiles, mask, prior, groups, sel, rows)
    chosen = None
    if rows is not None:                                               # §10.3.1 steps 4-6
        chosen = [t.index for t in tiles if sel[t.index]]
        tensors["anchor.voxel"] = tensors["anchor.voxel"][rows]
        tensors["anchor.mask"] = tensors["anchor.mask"][rows]
        dims = _rebase_regions(dims, groups, tensors, rows)
    tensors["anchor.feat"] = attrs["feat"]
    tensors["anchor.scaling"] = attrs["scaling"]
    tensors["anchor.offsets"] = attrs["offsets"]
    ordered = {}
    for name, dt, shape in dims.tensor_specs():
        a = tensors[name]
        assert tuple(a.shape) == tuple(shape), (name, a.shape, shape)
        ordered[name] = a
    return Decoded(dims, rate, ordered, symbols, chosen)


def _rebase_regions(dims: Dims, groups: dict, tensors: dict, rows) -> Dims:
    """§10.3.1 step 5: each general group's regions re-based onto the N' output anchors;
    returns the output's dimensions (N', R' per group; every other dimension the stream's)."""
    out = {"N": len(rows)}
    for g, field in (("feat", "feat_regions"), ("scaling", "scaling_regions")):
        grp = groups[g]
        base = f"quant.{g}"
        for t in ("start", "basis_u", "basis_s", "basis_v"):
            tensors.pop(f"{base}.regions.{t}", None)
        if not grp.bases:                   # not a general lattice: R = 1, nothing stored
            continue
        kept, starts = rebase(grp.region_starts, rows)
        U, s, V = grp.bases[kept[0]]
        tensors[f"{base}.basis_u"], tensors[f"{base}.basis_s"], tensors[f"{base}.basis_v"] = U, s, V
        if len(kept) > 1:
            tensors[f"{base}.regions.start"] = np.array(starts[1:], np.int32)
            tensors[f"{base}.regions.basis_u"] = np.stack([grp.bases[r][0] for r in kept[1:]])
            tensors[f"{base}.regions.basis_s"] = np.stack([grp.bases[r][1] for r in kept[1:]])
            tensors[f"{base}.regions.basis_v"] = np.stack([grp.bases[r][2] for r in kept[1:]])
        out[field] = len(kept)
    return replace(dims, **out)


def decode_file(path, rate: int | None = None, limits: Limits | None = None, region=None,
                prefix: bool = False):
    box = None if region is None else parse_region(region)      # refused before reading
    with open(path, "rb") as fh:
        data = fh.read()
    return decode_bytes(data, rate, limits, box, prefix)
