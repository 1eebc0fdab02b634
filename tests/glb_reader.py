"""A small GLB reader written from the glTF 2.0 spec, independent of vfit's writer (struct + json + NumPy).

It checks the container as it reads it and decodes accessors the way a viewer must: ``byteStride`` honoured,
normalized integers dequantized by KHR_mesh_quantization's formulas (``max(c / 32767, -1)`` for SHORT,
``max(c / 127, -1)`` for BYTE). Sparse accessors are not supported (vfit writes none; the reader says so).
"""
import json
import struct
from pathlib import Path

import numpy as np

DTYPES = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}
WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}


def parse_glb(path):
    """(json document, BIN chunk bytes) of a GLB file, its header, chunk types and padding checked."""
    data = Path(path).read_bytes()
    magic, version, total = struct.unpack_from("<4sII", data, 0)
    assert (magic, version, total) == (b"glTF", 2, len(data))
    js_len, js_type = struct.unpack_from("<I4s", data, 12)
    assert js_type == b"JSON" and js_len % 4 == 0
    doc = json.loads(data[20:20 + js_len])
    bin_len, bin_type = struct.unpack_from("<I4s", data, 20 + js_len)
    assert bin_type == b"BIN\0" and bin_len % 4 == 0
    assert 28 + js_len + bin_len == len(data)
    return doc, data[28 + js_len:28 + js_len + bin_len]


def raw_accessor(doc, blob, index):
    """The stored component values of accessor ``index``: (count, width) or (count,), its own dtype."""
    acc = doc["accessors"][index]
    assert "sparse" not in acc, "this reader does not decode sparse accessors"
    view = doc["bufferViews"][acc["bufferView"]]
    dtype = np.dtype(DTYPES[acc["componentType"]])
    width = WIDTH[acc["type"]]
    stride = view.get("byteStride", dtype.itemsize * width)
    start = view["byteOffset"] + acc.get("byteOffset", 0)
    assert start + stride * (acc["count"] - 1) + dtype.itemsize * width <= view["byteOffset"] + view["byteLength"]
    rows = np.frombuffer(blob, np.uint8, stride * acc["count"], start).reshape(acc["count"], stride)
    a = rows[:, :dtype.itemsize * width].copy().view(dtype)
    return a if acc["type"] != "SCALAR" else a.ravel()


def accessor(doc, blob, index):
    """Accessor ``index`` as float64 values (dequantized when normalized), or its integers (indices)."""
    acc = doc["accessors"][index]
    a = raw_accessor(doc, blob, index)
    if not acc.get("normalized"):
        return a.astype(np.float64) if a.dtype.kind == "f" else a
    top = float(np.iinfo(a.dtype).max)
    if a.dtype.kind == "i":
        return np.maximum(a / top, -1.0)
    return a / top


def primitive(doc, blob, name):
    """{attribute: array, "indices": (T, 3)} of the mesh called ``name``."""
    mesh = next(m for m in doc["meshes"] if m["name"] == name)
    prim = mesh["primitives"][0]
    out = {k: accessor(doc, blob, i) for k, i in prim["attributes"].items()}
    out["indices"] = accessor(doc, blob, prim["indices"]).reshape(-1, 3)
    return out


def morph_frames(doc, blob, name):
    """(positions, normals) of every frame of the mesh ``name``: base + target k, each (f, N, 3) float64,
    with the viewer's float32 sum; normals renormalized as a viewer does before shading."""
    prim = next(m for m in doc["meshes"] if m["name"] == name)["primitives"][0]
    base_p = accessor(doc, blob, prim["attributes"]["POSITION"]).astype(np.float32)
    base_n = accessor(doc, blob, prim["attributes"]["NORMAL"]).astype(np.float32)
    pos, nrm = [base_p], [base_n]
    for t in prim.get("targets", []):
        pos.append(base_p + accessor(doc, blob, t["POSITION"]).astype(np.float32))
        nrm.append(base_n + accessor(doc, blob, t["NORMAL"]).astype(np.float32))
    nrm = np.array(nrm, dtype=np.float64)
    return np.array(pos, dtype=np.float64), nrm / np.linalg.norm(nrm, axis=-1, keepdims=True)
