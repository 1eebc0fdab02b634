"""Binary glTF 2.0 (``.glb``) scene writer: body and garment in one file any 3D tool opens.

One node and one mesh per part, named after the part, in metres, Y up (vfit's frame is glTF's:
nothing is converted); each mesh is one indexed triangle primitive (polygons fan-triangulated)
with POSITION, smooth NORMAL, TEXCOORD_0 if the mesh has UVs, COLOR_0 if colours are given, and a
plain metallic-roughness material.

Why a hand-written writer and not trimesh's exporter: a trimesh mesh holds either a texture
visual (UVs) or a colour visual, not both, and the drape scene needs a garment's UVs *and* its
fit-map colours. glTF itself is simple enough: a JSON chunk and a BIN chunk, each padded to 4
bytes; every attribute here is a 4-byte component type, so every accessor starts aligned.

Conventions the caller should know:

- glTF wants one UV per vertex, so a vertex used with several UVs (a seam) is split into one
  glTF vertex per distinct (vertex, UV) pair; positions, normals and colours are copied to the
  copies, so seams stay invisible. Normals are computed before the split, on the polygon mesh.
- Corners without a UV (``face_uvs == -1``) get UV (0, 0); a viewer then samples one texel there,
  which is harmless for the untextured materials written here.
- glTF's V axis points down the image (origin top-left), OBJ's up: TEXCOORD_0 is (u, 1 - v).
- glTF vertex colours and material colours are *linear*; the sRGB colours given are converted,
  so a viewer shows them as given. They are stored as float VEC3 (exact, read by Blender and
  three.js). With colours, the material's base colour is white, since glTF multiplies the two.
"""
from __future__ import annotations

import hashlib
import json
import struct
from pathlib import Path
from typing import NamedTuple

import numpy as np

from vfit_engine.errors import InputError
from vfit_engine.geometry import vertex_normals
from vfit_engine.io import gltf_quantize
from vfit_engine.io.atomic import atomic_write

_FLOAT, _UINT = 5126, 5125  # glTF componentType codes
_COMPONENT = {np.dtype(np.float32): _FLOAT, np.dtype(np.uint32): _UINT, np.dtype(np.int16): 5122,
              np.dtype(np.int8): 5120}
_ARRAY_BUFFER, _ELEMENT_ARRAY_BUFFER = 34962, 34963
_TRIANGLES = 4
#: Default material colours (sRGB): skin for the body, a light grey-blue fabric for anything else.
_SKIN_SRGB = (0.87, 0.70, 0.60)
_FABRIC_SRGB = (0.60, 0.64, 0.75)


class ScenePart(NamedTuple):
    """One named mesh of a scene (a plain tuple ``(name, mesh, verts, colors)`` works too).

    Attributes
    ----------
    name : str
        Node and mesh name shown by viewers, e.g. ``"body"``, ``"garment"``.
    mesh : MeshData
        Topology, UVs (``uvs`` (t, 2), ``face_uvs`` (k,) with -1 for none) and default positions.
    verts : (n, 3) float, metres, or None
        Positions written instead of ``mesh.verts`` (same count and order), e.g. a draped state.
    colors : (n, 3) float sRGB in [0, 1] or (n, 3) uint8, or None
        Per-vertex colours (a fit map); None uses ``mesh.colors`` if the mesh has any.
    base_color : (3,) float sRGB or None
        Material colour without vertex colours; None: skin for ``"body"``, fabric otherwise.
    double_sided : bool or None
        None: single-sided for ``"body"`` (a closed surface), double-sided otherwise, because a
        garment is an open surface whose inside shows through its openings.
    """

    name: str
    mesh: object
    verts: np.ndarray | None = None
    colors: np.ndarray | None = None
    base_color: tuple | None = None
    double_sided: bool | None = None


def write_scene_glb(path, parts):
    """Write ``parts`` as one binary glTF 2.0 scene, atomically.

    Parameters
    ----------
    path : str or Path
        Output file, conventionally ``*.glb``.
    parts : sequence of ScenePart or of tuples ``(name, mesh[, verts[, colors]])``

    Returns
    -------
    Path

    Raises
    ------
    InputError
        ``glb part 'garment': <problem>`` for non-finite positions, UVs or colours, indices out of
        range, a mesh without triangles or colours of the wrong shape; no file is written then.
    """
    parts = [ScenePart(*p) for p in parts]
    if not parts:
        raise InputError("glb scene: no parts to write")
    # validate and build every part before opening the file: a bad part leaves nothing behind
    buf = _Buffer()
    doc = {"asset": {"version": "2.0", "generator": "vfit"}, "scene": 0,
           "scenes": [{"nodes": list(range(len(parts)))}], "nodes": [], "meshes": [], "materials": []}
    for i, part in enumerate(parts):
        attributes, indices = _part_arrays(part)
        acc = {key: buf.add(arr, _ARRAY_BUFFER, bounds=key == "POSITION") for key, arr in attributes.items()}
        prim = {"attributes": acc, "indices": buf.add(indices, _ELEMENT_ARRAY_BUFFER),
                "material": i, "mode": _TRIANGLES}
        doc["nodes"].append({"name": part.name, "mesh": i})
        doc["meshes"].append({"name": part.name, "primitives": [prim]})
        doc["materials"].append(_material(part, "COLOR_0" in attributes))
    doc.update(buf.json_fields())
    data = _glb_bytes(doc, buf.data())
    path = Path(path)
    with atomic_write(path, "wb") as f:
        f.write(data)
    return path


def write_animation_glb(path, parts, frames, fps):
    """Write ``parts`` animated through ``frames`` as one binary glTF 2.0 file, atomically.

    Each part's mesh carries one morph target per frame after the first (the positions' and normals' change
    from frame 0, at the glTF vertices of the split seams), and an animation sets the weight of frame ``k``'s
    target to 1 from time ``k / fps`` on (STEP interpolation), the others to 0: Blender (shape keys) and
    three.js (morph targets) play it frame by frame, the positions given to within 0.015 mm.

    The targets are stored compactly (:mod:`vfit_engine.io.gltf_quantize`), so the file lists
    ``KHR_mesh_quantization`` in ``extensionsUsed`` and ``extensionsRequired``: a viewer must support it
    (checked: Blender 3.4's importer, three.js r187's GLTFLoader, the Khronos glTF validator). A POSITION delta
    is a normalized int16 (1/32767 m steps, error <= 0.015 mm) unless some component of that target exceeds
    1 m, which stays float32; a NORMAL delta is a normalized int8 (under 0.4 degrees) unless a component
    exceeds 1 (only a normal turned past 60 degrees can), which stays float32. Identical arrays are written
    once and shared (a walk's repeating body frames, the parts' common weight track). The base mesh (frame 0)
    is float32, as :func:`write_scene_glb` writes it. The 60-frame walk of male_casualsuit02 (BENCHMARKS.md,
    "Animated fitting") went from 25.3 MB (all float32) to 11.1 MB.

    Parameters
    ----------
    path : str or Path
    parts : sequence of ScenePart or tuples
        As :func:`write_scene_glb`; ``verts`` is ignored (frame 0 is the base).
    frames : sequence of (f, n_part, 3) float arrays, m
        Every part's positions in every frame (the same ``f`` >= 1 for all parts).
    fps : float
        Frames per second.

    Returns
    -------
    Path
    """
    parts = [ScenePart(*p) for p in parts]
    frames = [np.asarray(f, dtype=np.float64) for f in frames]
    if not parts or len(frames) != len(parts):
        raise InputError("glb animation: give one (frames, n, 3) array per part")
    count = frames[0].shape[0]
    if count < 1 or any(f.ndim != 3 or f.shape[0] != count for f in frames):
        raise InputError("glb animation: every part needs the same number (>= 1) of frames")
    if not (np.isfinite(fps) and fps > 0):
        raise InputError(f"glb animation: fps must be > 0, got {fps!r}")
    buf = _Buffer()
    doc = {"asset": {"version": "2.0", "generator": "vfit"}, "scene": 0,
           "scenes": [{"nodes": list(range(len(parts)))}], "nodes": [], "meshes": [], "materials": []}
    times = buf.add(np.ascontiguousarray(np.arange(count) / float(fps), dtype=np.float32), None, bounds=True)
    weights = np.zeros((count, max(count - 1, 0)), dtype=np.float32)
    weights[np.arange(1, count), np.arange(count - 1)] = 1.0
    samplers, channels = [], []
    for i, (part, pos) in enumerate(zip(parts, frames)):
        part = part._replace(verts=pos[0])
        attributes, indices, src = _part_arrays(part, with_src=True)
        if pos.shape[1:] != (part.mesh.n_verts, 3) or not np.all(np.isfinite(pos)):
            raise InputError(f"glb part {part.name!r}: frames must be finite, ({count}, {part.mesh.n_verts}, 3)")
        acc = {key: buf.add(arr, _ARRAY_BUFFER, bounds=key == "POSITION") for key, arr in attributes.items()}
        targets = [_morph_target(buf, part.mesh, p, src, attributes) for p in pos[1:]]
        prim = {"attributes": acc, "indices": buf.add(indices, _ELEMENT_ARRAY_BUFFER), "material": i,
                "mode": _TRIANGLES}
        mesh = {"name": part.name, "primitives": [prim]}
        if targets:
            prim["targets"] = targets
            mesh["weights"] = [0.0] * len(targets)
            samplers.append({"input": times, "output": buf.add(weights.ravel(), None), "interpolation": "STEP"})
            channels.append({"sampler": len(samplers) - 1, "target": {"node": i, "path": "weights"}})
        doc["nodes"].append({"name": part.name, "mesh": i})
        doc["meshes"].append(mesh)
        doc["materials"].append(_material(part, "COLOR_0" in attributes))
    if channels:
        doc["animations"] = [{"name": "animation", "samplers": samplers, "channels": channels}]
    if buf.quantized:  # the integer targets mean nothing to a reader without the extension: required
        doc["extensionsUsed"] = doc["extensionsRequired"] = [gltf_quantize.EXTENSION]
    doc.update(buf.json_fields())
    data = _glb_bytes(doc, buf.data())
    path = Path(path)
    with atomic_write(path, "wb") as f:
        f.write(data)
    return path


def _morph_target(buf, mesh, pos, src, base):
    """One frame's morph target ``{"POSITION": accessor, "NORMAL": accessor}`` against the base attributes.

    ``pos`` (n, 3) m are the frame's positions at the source vertices, ``src`` the source vertex of every glTF
    vertex, ``base`` the part's float32 base attributes as written.
    """
    normals = vertex_normals(pos, mesh.face_verts, mesh.face_offsets)
    normals[np.linalg.norm(normals, axis=1) == 0] = (0.0, 1.0, 0.0)  # as the base: unit normals everywhere
    dpos, pos_q = gltf_quantize.position_delta(pos[src], base["POSITION"])
    dnrm, nrm_q = gltf_quantize.normal_delta(normals[src], base["NORMAL"])
    return {"POSITION": buf.add(dpos, _ARRAY_BUFFER, bounds=True, normalized=pos_q),
            "NORMAL": buf.add(dnrm, _ARRAY_BUFFER, normalized=nrm_q)}


def _part_arrays(part, with_src=False):
    """Validate one part; return ({attribute: float32 (N, c)}, uint32 (3T,) indices) and, ``with_src``, the
    source vertex of every glTF vertex."""
    name, mesh = part.name, part.mesh

    def bad(problem):
        return InputError(f"glb part {name!r}: {problem}")

    verts = mesh.verts if part.verts is None else part.verts
    verts = np.asarray(verts, dtype=np.float64)
    n = mesh.n_verts
    if verts.shape != (n, 3):
        raise bad(f"positions have shape {verts.shape}, the mesh needs ({n}, 3)")
    if not np.all(np.isfinite(verts)):
        raise bad("positions contain NaN or infinity")
    fv = mesh.face_verts
    if fv.size and (fv.min() < 0 or fv.max() >= n):
        raise bad(f"face vertex index out of range 0..{n - 1}")
    tri = mesh.triangles()
    if tri.shape[0] == 0:
        raise bad("mesh is empty (no triangles)")
    colors = _linear_colors(part, n, bad)
    normals = vertex_normals(verts, fv, mesh.face_offsets)
    # glTF requires unit normals: a vertex on no face or on degenerate faces gets +Y
    normals[np.linalg.norm(normals, axis=1) == 0] = (0.0, 1.0, 0.0)

    src, uv, tri = _split_seams(mesh, tri, bad)
    attributes = {"POSITION": verts[src], "NORMAL": normals[src]}
    if uv is not None:
        attributes["TEXCOORD_0"] = np.stack([uv[:, 0], 1.0 - uv[:, 1]], axis=1)
    if colors is not None:
        attributes["COLOR_0"] = colors[src]
    attributes = {k: np.ascontiguousarray(a, dtype=np.float32) for k, a in attributes.items()}
    indices = np.ascontiguousarray(tri, dtype=np.uint32).ravel()
    return (attributes, indices, src) if with_src else (attributes, indices)


def _split_seams(mesh, tri, bad):
    """One glTF vertex per distinct (vertex, UV) pair of the triangle corners.

    Returns
    -------
    src : (N,) int64
        Source vertex of every glTF vertex; ``arange(n)`` without UVs (order kept).
    uv : (N, 2) float64 or None
        UV of every glTF vertex (OBJ convention, V up); (0, 0) for corners without one.
    tri : (T, 3) int64
        Triangles over the glTF vertices.
    """
    n = mesh.n_verts
    if mesh.uvs is None or mesh.face_uvs is None:
        return np.arange(n), None, tri
    uvs = np.asarray(mesh.uvs, dtype=np.float64).reshape(-1, 2)
    t = uvs.shape[0]
    if mesh.face_uvs.shape != mesh.face_verts.shape:
        raise bad(f"face_uvs has {mesh.face_uvs.size} corners, faces have {mesh.face_verts.size}")
    if mesh.face_uvs.size and (mesh.face_uvs.min() < -1 or mesh.face_uvs.max() >= t):
        raise bad(f"face UV index out of range -1..{t - 1}")
    if not np.all(np.isfinite(uvs)):
        raise bad("UVs contain NaN or infinity")
    tri_uv = mesh.triangle_uvs()
    # a vertex no face uses is kept (with no UV) so every source vertex appears at least once
    unused = np.setdiff1d(np.arange(n), tri)
    vert = np.concatenate([tri.ravel(), unused])
    uv_id = np.concatenate([tri_uv.ravel(), np.full(unused.size, -1)])
    # key sorts by vertex, then UV: glTF vertices come in source order, seam copies adjacent
    keys = vert * (t + 1) + (uv_id + 1)
    uniq, inverse = np.unique(keys, return_inverse=True)
    src, uv_of = uniq // (t + 1), uniq % (t + 1) - 1
    uv = np.zeros((src.size, 2))
    has = uv_of >= 0
    uv[has] = uvs[uv_of[has]]
    return src, uv, inverse.ravel()[: tri.size].reshape(-1, 3)


def _linear_colors(part, n, bad):
    """(n, 3) float64 linear colours of a part, or None."""
    colors = part.colors if part.colors is not None else getattr(part.mesh, "colors", None)
    if colors is None:
        return None
    colors = np.asarray(colors)
    if colors.shape != (n, 3):
        raise bad(f"colours have shape {colors.shape}, the mesh needs ({n}, 3)")
    if colors.dtype == np.uint8:
        srgb = colors / 255.0
    else:
        srgb = colors.astype(np.float64)
        if not np.all(np.isfinite(srgb)) or srgb.min() < 0.0 or srgb.max() > 1.0:
            raise bad("float colours must be finite and in [0, 1] (sRGB)")
    return _srgb_to_linear(srgb)


def _srgb_to_linear(c):
    """Linear values of sRGB colours in [0, 1] (IEC 61966-2-1 transfer function)."""
    c = np.asarray(c, dtype=np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def _material(part, has_colors):
    """A metallic-roughness material: skin or fabric colour, white under vertex colours."""
    body = part.name == "body"
    srgb = part.base_color if part.base_color is not None else (_SKIN_SRGB if body else _FABRIC_SRGB)
    rgb = [1.0, 1.0, 1.0] if has_colors else [float(x) for x in _srgb_to_linear(srgb)]
    double = (not body) if part.double_sided is None else bool(part.double_sided)
    return {"name": f"{part.name}_material", "doubleSided": double,
            "pbrMetallicRoughness": {"baseColorFactor": rgb + [1.0], "metallicFactor": 0.0,
                                     "roughnessFactor": 0.6 if body else 0.9}}


class _Buffer:
    """The BIN chunk under construction: one bufferView and one accessor per distinct array.

    An array identical to one added before (same bytes, type and use) gets the earlier accessor back: a walk
    repeats its cycle, so the body's later frames are often byte for byte an earlier frame's target, and every
    part's weight track is the same; sharing them is exact.
    """

    def __init__(self):
        self.chunks, self.views, self.accessors, self.length = [], [], [], 0
        self.quantized = False  # any normalized integer attribute written: KHR_mesh_quantization required
        self._seen = {}

    def add(self, arr, target, bounds=False, normalized=False):
        """Append a float32, int16 or int8 (N, c) or a uint32 (N,) array; return its accessor index.

        ``normalized`` marks integer data read as ``c / max`` (KHR_mesh_quantization); ``bounds`` writes
        min/max, in the stored component values as the spec asks (integers for integer data).
        """
        raw, stride = _element_bytes(arr, target)
        key = (hashlib.sha256(raw).digest(), arr.dtype.str, arr.shape, target, bounds, normalized)
        if key in self._seen:
            return self._seen[key]
        view = {"buffer": 0, "byteOffset": self.length, "byteLength": len(raw)}
        if stride:
            view["byteStride"] = stride
        if target is not None:  # animation data: a buffer view without a GPU target
            view["target"] = target
        self.views.append(view)
        # each view starts on a 4-byte boundary (glTF's alignment for every component type): pad the chunk
        pad = b"\0" * (-len(raw) % 4)
        self.chunks.append(raw + pad)
        self.length += len(raw) + len(pad)
        kind = "SCALAR" if arr.ndim == 1 else f"VEC{arr.shape[1]}"
        acc = {"bufferView": len(self.views) - 1, "byteOffset": 0, "count": int(arr.shape[0]), "type": kind,
               "componentType": _COMPONENT[arr.dtype]}
        if normalized:
            acc["normalized"] = True
            self.quantized = True
        if bounds:  # the spec requires min/max on POSITION, exactly the values written
            acc["min"] = [x.item() for x in np.atleast_1d(arr.min(axis=0))]
            acc["max"] = [x.item() for x in np.atleast_1d(arr.max(axis=0))]
        self.accessors.append(acc)
        self._seen[key] = len(self.accessors) - 1
        return len(self.accessors) - 1

    def data(self):
        return b"".join(self.chunks)

    def json_fields(self):
        return {"buffers": [{"byteLength": self.length}], "bufferViews": self.views, "accessors": self.accessors}


def _element_bytes(arr, target):
    """(bytes, byteStride or 0) of an array, each vertex-attribute element padded to a multiple of 4 bytes.

    glTF requires every element of a vertex attribute to start on a 4-byte boundary: an int16 VEC3 (6 bytes)
    is written as 8 with ``byteStride`` 8, an int8 VEC3 as 4. Float32 and uint32 data need no padding.
    """
    arr = np.ascontiguousarray(arr)
    size = arr.itemsize * (arr.shape[1] if arr.ndim == 2 else 1)
    if target != _ARRAY_BUFFER or size % 4 == 0:
        return arr.tobytes(), 0
    padded = np.zeros((arr.shape[0], -(-size // 4) * 4 // arr.itemsize), dtype=arr.dtype)
    padded[:, :arr.shape[1]] = arr
    return padded.tobytes(), padded.shape[1] * arr.itemsize


def _glb_bytes(doc, bin_data):
    """The GLB container: 12-byte header, JSON chunk (space-padded), BIN chunk (zero-padded)."""
    js = json.dumps(doc, separators=(",", ":")).encode("utf-8")
    js += b" " * ((-len(js)) % 4)
    bin_data += b"\0" * ((-len(bin_data)) % 4)
    total = 12 + 8 + len(js) + 8 + len(bin_data)
    return b"".join([struct.pack("<4sII", b"glTF", 2, total),
                     struct.pack("<I4s", len(js), b"JSON"), js,
                     struct.pack("<I4s", len(bin_data), b"BIN\0"), bin_data])
