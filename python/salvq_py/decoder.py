"""The decoding processes: chunk order and per-chunk decoding of the anchors profile (§1.5,
§7.4 rate selection) and of the explicit-Gaussians profile (§3.7), told apart by the first
chunk (§1.5)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .container import Chunk, Limits, check_signature, read_chunk
from .entropy import Prior, decode_amsk, decode_layer, payload_method
from .errors import SalvqError
from .explicit import GHead, parse_ghed, parse_glay, parse_gqua
from .gatt import decode_gatt
from .gaussians import reconstruct_gaussians
from .geometry import decode_apos
from .hyperprior import (grid_body_length, mlp_grid_tensors, parse_grid,
                         parse_mlps, touched_entries)
from .model import Dims, parse_head
from .quantizers import parse_quan, quan_body_length
from .tiles import check_tiles, parse_tils, split_tiles

KNOWN_CRITICAL = ("HEAD", "MLPS", "QUAN", "TILS", "APOS", "GRID", "AMSK", "AFEA", "ASCL",
                  "AOFF", "SEND")                                     # Table 1-3
EXPLICIT_CRITICAL = ("GHED", "GQUA", "GLAY", "TILS", "APOS", "GATT", "SEND")   # Table 3-2


@dataclass
class Decoded:
    """An anchors-profile decode."""
    dims: Dims
    rate: int
    tensors: dict          # Table 2-1 tensors (present ones), numpy arrays
    symbols: dict          # feat [N, F], scaling [N, S], offsets [N, K, 3], int64
    profile = "anchors"


@dataclass
class ExplicitDecoded:
    """An explicit-profile decode (§3): the selected layer's Gaussians."""
    head: GHead
    rate: int
    integers: dict         # Table 11-2, in order
    tensors: dict          # Table 3-4 (the decoded Gaussians), in order
    profile = "explicit"


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


def decode_bytes(data: bytes, rate: int | None = None, limits: Limits | None = None):
    """Decode a stream of either profile: a `Decoded` (anchors) or an `ExplicitDecoded`."""
    limits = limits or Limits()
    pos = check_signature(data)
    first, pos = read_chunk(data, pos, limits)
    if first.tag == "GHED":                                            # §1.5, §3
        return _decode_explicit(data, first, pos, rate, limits)
    return _decode_anchors(data, first, pos, rate, limits)


def _decode_explicit(data: bytes, chunk: Chunk, pos: int, rate: int | None,
                     limits: Limits) -> ExplicitDecoded:
    """§3.7: GHED GQUA (GLAY TILS APOS GATT)×L SEND; the selected layer's chunks are decoded
    as they are read, the other layers' are only checked as chunks and for their order."""
    order = ["GHED"]
    due = 0
    layer = -1
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
                coded = head.coded_rates()
                order = ["GHED", "GQUA"] + ["GLAY", "TILS", "APOS", "GATT"] * len(coded) + ["SEND"]
            elif tag == "GQUA":
                groups = parse_gqua(p, head)
            elif tag == "SEND":
                _send(chunk, data, pos)
                break
            else:
                if tag == "GLAY":
                    layer += 1
                if coded[layer] == rate:                               # the selected layer
                    if tag == "GLAY":
                        lay = parse_glay(p, head)
                    elif tag == "TILS":
                        payload_method(tag, p, 0)
                        tiles = parse_tils(p, head.N, lay.coord_bits)
                    elif tag == "APOS":
                        payload_method(tag, p, 1)
                        voxels = decode_apos(split_tiles("APOS", p, 1, len(tiles)), tiles)
                        check_tiles(tiles, voxels)
                    else:
                        sym = decode_gatt(p, head, lay, tiles, voxels)
        chunk, pos = read_chunk(data, pos, limits)
    integers = {
        "gaussian.voxel": voxels.astype(np.int32),
        "symbols.coordinates": sym.coordinates,
        "symbols.rotation_index": sym.rotation_index,
        "symbols.size_class": sym.size_class,
        "symbols.refinement": sym.refinement,
    }
    gaussians = reconstruct_gaussians(head, groups, rate, lay, voxels, sym)
    return ExplicitDecoded(head, rate, integers, gaussians)


def _decode_anchors(data: bytes, chunk: Chunk, pos: int, rate: int | None,
                    limits: Limits) -> Decoded:
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
            mask = decode_amsk(p, dims, tiles)
            tensors["anchor.mask"] = mask
        elif tag in ("AFEA", "ASCL", "AOFF"):
            if tag == "AFEA":
                layer_index += 1
            if layer_of[layer_index] == rate:
                selected[tag] = p
        elif tag == "SEND":
            _send(chunk, data, pos)                                        # rules 4-5
            break
    prior = Prior(dims, mlp, groups, rate, voxels, grids)
    attrs, symbols = decode_layer(selected, dims, tiles, mask, prior, groups)
    tensors["anchor.feat"] = attrs["feat"]
    tensors["anchor.scaling"] = attrs["scaling"]
    tensors["anchor.offsets"] = attrs["offsets"]
    ordered = {}
    for name, dt, shape in dims.tensor_specs():
        a = tensors[name]
        assert tuple(a.shape) == tuple(shape), (name, a.shape, shape)
        ordered[name] = a
    return Decoded(dims, rate, ordered, symbols)


def decode_file(path, rate: int | None = None, limits: Limits | None = None):
    with open(path, "rb") as fh:
        data = fh.read()
    return decode_bytes(data, rate, limits)
