"""PLY reader and writer (ASCII, binary little- and big-endian) keeping vertex and face order.

Read: ``vertex`` x, y, z (any scalar type), optional red/green/blue (colours, stored as uint8) and
s/t, u/v or texture_u/texture_v (per-vertex UVs); ``face`` with a list property ``vertex_indices``
(or ``vertex_index``) of any size. Other properties and elements are skipped.
Header comments are UTF-8 (they may name files), everything else ASCII.
Write: binary little-endian by default, x y z as float64 (``double``: metres need more than
float32's 7 digits to round-trip exactly), optional red green blue uchar, faces as ``list uchar int``.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from vfit_engine.errors import InputError
from vfit_engine.io.atomic import atomic_write
from vfit_engine.io.meshdata import MAX_VERTS, MeshData

_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}


def _parse_header(data, path):
    end = data.find(b"end_header")
    if not data.startswith(b"ply") or end < 0:
        raise InputError(f"{path}: not a PLY file (no 'ply' magic or no 'end_header')")
    nl = data.find(b"\n", end)
    body_start = len(data) if nl < 0 else nl + 1
    header = data[:end].decode("utf-8", errors="replace").splitlines()  # comments may name files in UTF-8
    fmt = None
    elements = []  # [name, count, [(prop name, dtype) or (name, (count dtype, item dtype))]]
    for raw in header[1:]:
        words = raw.split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        try:
            if words[0] == "format":
                fmt = words[1]
            elif words[0] == "element":
                elements.append([words[1], int(words[2]), []])
            elif words[0] == "property":
                if words[1] == "list":
                    elements[-1][2].append((words[4], (_TYPES[words[2]], _TYPES[words[3]])))
                else:
                    elements[-1][2].append((words[2], _TYPES[words[1]]))
        except (IndexError, KeyError, ValueError):
            raise InputError(f"{path}: bad PLY header line {raw.strip()!r}") from None
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise InputError(f"{path}: unsupported PLY format {fmt!r}")
    return fmt, elements, body_start


def _read_binary_element(data, pos, count, props, endian, path):
    """Return ({prop: array or list-of-arrays (as (offsets, values))}, new pos)."""
    if all(not isinstance(t, tuple) for _, t in props):
        dt = np.dtype([(n, endian + t) for n, t in props])
        nbytes = dt.itemsize * count
        if pos + nbytes > len(data):
            raise InputError(f"{path}: PLY file truncated")
        arr = np.frombuffer(data, dtype=dt, count=count, offset=pos)
        return {n: arr[n] for n, _ in props}, pos + nbytes
    # one list property (faces): try the uniform-size fast path, else walk the records
    if len(props) == 1 and count:
        name, (ct, it) = props[0]
        ct_dt, it_dt = np.dtype(endian + ct), np.dtype(endian + it)
        if pos + ct_dt.itemsize > len(data):
            raise InputError(f"{path}: PLY file truncated")
        s = int(np.frombuffer(data, ct_dt, 1, pos)[0])
        rec = np.dtype([("n", ct_dt), ("i", it_dt, (s,))])
        if pos + rec.itemsize * count <= len(data):
            arr = np.frombuffer(data, rec, count, pos)
            if np.all(arr["n"] == s):
                offsets = np.arange(count + 1, dtype=np.int64) * s
                return {name: (offsets, arr["i"].reshape(-1).astype(np.int64))}, pos + rec.itemsize * count
    out = {n: [] for n, _ in props}
    for _ in range(count):
        for n, t in props:
            if isinstance(t, tuple):
                ct_dt, it_dt = np.dtype(endian + t[0]), np.dtype(endian + t[1])
                if pos + ct_dt.itemsize > len(data):
                    raise InputError(f"{path}: PLY file truncated")
                k = int(np.frombuffer(data, ct_dt, 1, pos)[0])
                pos += ct_dt.itemsize
                if pos + k * it_dt.itemsize > len(data):
                    raise InputError(f"{path}: PLY file truncated")
                out[n].append(np.frombuffer(data, it_dt, k, pos).astype(np.int64))
                pos += k * it_dt.itemsize
            else:
                dt = np.dtype(endian + t)
                out[n].append(np.frombuffer(data, dt, 1, pos)[0])
                pos += dt.itemsize
    res = {}
    for n, t in props:
        if isinstance(t, tuple):
            sizes = np.array([len(a) for a in out[n]], dtype=np.int64)
            offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
            vals = np.concatenate(out[n]) if out[n] else np.zeros(0, np.int64)
            res[n] = (offsets, vals)
        else:
            res[n] = np.array(out[n])
    return res, pos


def _read_ascii_element(lines, start, count, props, path):
    """Return ({prop: array or (offsets, values)}, next line index)."""
    block = lines[start:start + count]
    if len(block) < count:
        raise InputError(f"{path}: PLY file truncated")
    has_list = any(isinstance(t, tuple) for _, t in props)
    if not has_list:
        try:
            arr = np.array(" ".join(block).split(), dtype=np.float64).reshape(count, len(props))
        except ValueError:
            raise InputError(f"{path}: bad number in PLY element data near line {start + 1}") from None
        return {n: arr[:, j] for j, (n, _) in enumerate(props)}, start + count
    out = {n: [] for n, _ in props}
    for k, line in enumerate(block):
        words = line.split()
        j = 0
        try:
            for n, t in props:
                if isinstance(t, tuple):
                    m = int(words[j])
                    out[n].append(np.array(words[j + 1:j + 1 + m], dtype=np.int64))
                    if len(out[n][-1]) != m:
                        raise ValueError
                    j += 1 + m
                else:
                    out[n].append(float(words[j]))
                    j += 1
        except (ValueError, IndexError):
            raise InputError(f"{path}: bad PLY element line {start + k + 1}: {line.strip()[:60]!r}") from None
    res = {}
    for n, t in props:
        if isinstance(t, tuple):
            sizes = np.array([len(a) for a in out[n]], dtype=np.int64)
            offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
            res[n] = (offsets, np.concatenate(out[n]) if out[n] else np.zeros(0, np.int64))
        else:
            res[n] = np.array(out[n])
    return res, start + count


def read_ply(path, max_verts=MAX_VERTS):
    """Read a PLY mesh (see the module docstring).

    Returns
    -------
    MeshData
        In the file's units; ``colors`` (n, 3) uint8 when the file has red/green/blue.
    """
    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        raise InputError(f"cannot read {path}: {exc.strerror or exc}") from None
    if data.startswith(b"\xef\xbb\xbf"):  # a UTF-8 byte-order mark before the magic (Windows editors)
        data = data[3:]
    fmt, elements, pos = _parse_header(data, path)
    names = [e[0] for e in elements]
    if "vertex" not in names:
        raise InputError(f"{path}: PLY file has no vertex element")
    nverts = elements[names.index("vertex")][1]
    if nverts == 0:
        raise InputError(f"{path}: no vertices")
    if nverts > max_verts:
        raise InputError(f"{path}: {nverts} vertices, more than the limit of {max_verts}")
    values = {}
    if fmt == "ascii":
        lines = data[pos:].decode("ascii", errors="replace").splitlines()
        lines = [ln for ln in lines if ln.strip() and not ln.startswith("comment")]
        li = 0
        for name, count, props in elements:
            values[name], li = _read_ascii_element(lines, li, count, props, path)
    else:
        endian = "<" if fmt == "binary_little_endian" else ">"
        for name, count, props in elements:
            values[name], pos = _read_binary_element(data, pos, count, props, endian, path)
    vtx = values["vertex"]
    if not all(k in vtx for k in "xyz"):
        raise InputError(f"{path}: PLY vertex element lacks x, y or z")
    verts = np.stack([np.asarray(vtx[k], dtype=np.float64) for k in "xyz"], axis=1)
    colors = None
    if all(k in vtx for k in ("red", "green", "blue")):
        colors = np.stack([np.asarray(vtx[k]) for k in ("red", "green", "blue")], axis=1)
        colors = np.clip(np.rint(colors), 0, 255).astype(np.uint8)
    uvs = None
    for a, b in (("s", "t"), ("u", "v"), ("texture_u", "texture_v")):
        if a in vtx and b in vtx:
            uvs = np.stack([np.asarray(vtx[a], np.float64), np.asarray(vtx[b], np.float64)], axis=1)
            break
    offsets, fv = np.zeros(1, np.int64), np.zeros(0, np.int64)
    if "face" in values:
        for key in ("vertex_indices", "vertex_index"):
            if key in values["face"]:
                offsets, fv = values["face"][key]
                break
    fv = np.ascontiguousarray(fv, dtype=np.int64)
    if fv.size and (fv.min() < 0 or fv.max() >= nverts):
        bad = int(fv[(fv < 0) | (fv >= nverts)][0])
        raise InputError(f"{path}: face vertex index {bad} out of range (0..{nverts - 1})")
    if offsets.size > 1 and np.diff(offsets).min() < 3:
        raise InputError(f"{path}: face with fewer than 3 vertices")
    return MeshData(
        verts=np.ascontiguousarray(verts),
        face_offsets=np.ascontiguousarray(offsets, dtype=np.int64),
        face_verts=fv,
        uvs=uvs,
        face_uvs=None if uvs is None else fv.copy(),
        colors=colors,
    )


def write_ply(path, mesh, header=None, colors=None, binary=True, properties=None):
    """Write ``mesh`` as PLY atomically.

    Parameters
    ----------
    path : str or Path
    mesh : MeshData
    header : str or list of str or None
        Written as ``comment`` lines.
    colors : (n, 3) uint8 or None
        Per-vertex colours; defaults to ``mesh.colors``.
    binary : bool
        Binary little-endian (default) or ASCII.
    properties : dict or None
        Extra per-vertex values, name -> (n,) float, written as ``property float NAME`` (float32) after
        the colours (fit maps: ``strain``, ``ease_mm`` ...).
    """
    verts = np.ascontiguousarray(mesh.verts, dtype=np.float64)
    if not np.all(np.isfinite(verts)):
        raise InputError("refusing to write a mesh with NaN or infinite coordinates")
    n = verts.shape[0]
    if colors is None:
        colors = mesh.colors
    if colors is not None:
        colors = np.asarray(colors)
        if colors.shape != (n, 3):
            raise InputError(f"colours have shape {colors.shape}, mesh needs ({n}, 3)")
        colors = colors.astype(np.uint8)
    extra = {}
    for name, values in (properties or {}).items():
        values = np.asarray(values, dtype=np.float32).ravel()
        if values.shape != (n,) or not name.isidentifier():
            raise InputError(f"vertex property {name!r} has {values.size} values, mesh needs {n}")
        extra[name] = values
    sizes = mesh.face_sizes()
    if sizes.size and sizes.max() > 255:
        big = int(np.argmax(sizes))
        raise InputError(f"cannot write {path}: face {big + 1} has {int(sizes[big])} vertices, more than a PLY face "
                         "holds (255): write OBJ instead")
    lines = ["ply", "format " + ("binary_little_endian" if binary else "ascii") + " 1.0"]
    if header:
        for h in [header] if isinstance(header, str) else header:
            lines += ["comment " + s for s in str(h).splitlines()]
    lines += [f"element vertex {n}", "property double x", "property double y", "property double z"]
    if colors is not None:
        lines += ["property uchar red", "property uchar green", "property uchar blue"]
    lines += [f"property float {name}" for name in extra]
    lines += [f"element face {mesh.n_faces}", "property list uchar int vertex_indices", "end_header"]
    # UTF-8: a comment may name a file (jupe_été.obj); the keywords and numbers are ASCII, as PLY's readers expect
    head = ("\n".join(lines) + "\n").encode("utf-8", "backslashreplace")  # backslash: a name not in UTF-8
    if binary:
        vfields = [("x", "<f8"), ("y", "<f8"), ("z", "<f8")]
        if colors is not None:
            vfields += [("red", "u1"), ("green", "u1"), ("blue", "u1")]
        vfields += [(name, "<f4") for name in extra]
        varr = np.empty(n, dtype=np.dtype(vfields))
        varr["x"], varr["y"], varr["z"] = verts[:, 0], verts[:, 1], verts[:, 2]
        if colors is not None:
            varr["red"], varr["green"], varr["blue"] = colors[:, 0], colors[:, 1], colors[:, 2]
        for name, values in extra.items():
            varr[name] = values
        # each face record: uchar count, then count little-endian int32 (built in one buffer)
        m = mesh.n_faces
        rec_bytes = 1 + 4 * sizes
        fbuf = np.zeros(int(rec_bytes.sum()), dtype=np.uint8)
        starts = np.cumsum(rec_bytes) - rec_bytes
        fbuf[starts] = sizes.astype(np.uint8)
        corner_face = np.repeat(np.arange(m), sizes)
        corner_rank = np.arange(mesh.face_verts.size) - np.repeat(mesh.face_offsets[:-1], sizes)
        pos = starts[corner_face] + 1 + 4 * corner_rank
        idx_bytes = mesh.face_verts.astype("<i4").view(np.uint8).reshape(-1, 4)
        for b in range(4):
            fbuf[pos + b] = idx_bytes[:, b]
        payload = head + varr.tobytes() + fbuf.tobytes()
        with atomic_write(path, "wb") as f:
            f.write(payload)
        return
    body = []
    fmt = "%.17g %.17g %.17g" + (" %d %d %d" if colors is not None else "") + " %.9g" * len(extra) + "\n"
    cols = [verts] if colors is None else [verts, colors.astype(np.float64)]
    cols += [v.astype(np.float64)[:, None] for v in extra.values()]
    vals = np.concatenate(cols, axis=1)
    body.append((fmt * n) % tuple(vals.ravel().tolist()))
    o = mesh.face_offsets
    fv = mesh.face_verts.tolist()
    body.append("".join(
        f"{o[i + 1] - o[i]} " + " ".join(map(str, fv[o[i]:o[i + 1]])) + "\n" for i in range(mesh.n_faces)
    ))
    with atomic_write(path, "wb") as f:
        f.write(head + "".join(body).encode("ascii"))

