"""The decoding process (§1.5): chunk order, per-chunk decoding, the selected rate (§7.4)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .container import Limits, check_signature, read_chunk
from .entropy import Prior, decode_amsk, decode_layer, payload_method
from .errors import SalvqError
from .geometry import decode_apos
from .hyperprior import (grid_body_length, mlp_grid_tensors, parse_grid,
                         parse_mlps, touched_entries)
from .model import Dims, parse_head
from .quantizers import parse_quan, quan_body_length
from .tiles import check_tiles, parse_tils, split_tiles

KNOWN_CRITICAL = ("HEAD", "MLPS", "QUAN", "TILS", "APOS", "GRID", "AMSK", "AFEA", "ASCL",
                  "AOFF", "SEND")


@dataclass
class Decoded:
    dims: Dims
    rate: int
    tensors: dict          # Table 2-1 tensors (present ones), numpy arrays
    symbols: dict          # feat [N, F], scaling [N, S], offsets [N, K, 3], int64


def _fixed_length(tag: str, payload: bytes, method: int, body_len: int) -> bytes:
    """§1.6 steps 1-3 for a chunk whose body length is known."""
    payload_method(tag, payload, method)
    if len(payload) != 1 + body_len:
        raise SalvqError("ChunkSizeMismatch",
                         f"chunk {tag}: payload length {len(payload)}, expected {1 + body_len} [§1.6]")
    return payload[1:]


def decode_bytes(data: bytes, rate: int | None = None, limits: Limits | None = None) -> Decoded:
    limits = limits or Limits()
    pos = check_signature(data)
    first = True
    dims: Dims | None = None
    order: list[str] = ["HEAD"]
    due = 0
    layer_of: list[int] = []          # rate of each layer, in stream order
    layer_index = -1
    selected = {}
    tensors: dict = {}
    while True:
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
            coded = dims.coded_rates()
            if rate is None:
                rate = coded[0]
            if rate >= dims.M:
                raise SalvqError("FieldOutOfRange", f"field rate = {rate}, range 0 … {dims.M - 1} [§1.5]")
            if not (dims.rate_mask >> rate) & 1:
                raise SalvqError("RateNotCoded", f"rate {rate} has no symbol layer in the stream [§7.4]")
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
            tiles = parse_tils(p, dims)
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
            if len(p) != 0:
                raise SalvqError("ChunkSizeMismatch", f"chunk SEND: payload length {len(p)}, expected 0 [§1.5]")
            if pos != len(data):                                           # rule 5
                raise SalvqError("TrailingData", f"{len(data) - pos} bytes after SEND [§1.5]")
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


def decode_file(path, rate: int | None = None, limits: Limits | None = None) -> Decoded:
    with open(path, "rb") as fh:
        data = fh.read()
    return decode_bytes(data, rate, limits)
