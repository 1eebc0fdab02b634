"""Wavefront OBJ reader and writer that keep the file's vertex order, faces and UVs.

Reading
    ``v``, ``vt`` and ``f`` (``v``, ``v/vt``, ``v//vn``, ``v/vt/vn``, negative = relative indices,
    triangles, quads and n-gons); ``g``, ``o``, ``usemtl`` and ``mtllib`` are remembered; ``vn``,
    ``s``, ``l``, ``p`` and unknown statements are ignored. Materials and textures are never opened,
    so a missing ``.mtl`` does not matter. Topology comes from the ``v`` indices only: a UV seam
    never splits the cloth. Every ``v`` is kept, in order, even when no face uses it.
    ``\\`` line continuations are joined (line numbers in messages then count joined lines).

    Speed: lines are sorted by a plain Python loop, then each block is parsed at once in C
    (``numpy.fromstring``; face corners by a vectorised byte scan of the ``/``-separated fields).
    Measured (CPU time, 2-core box): MakeHuman's 19,158-vertex ``base.obj`` (59k lines) 0.075 s;
    a 300k-vertex quad grid with UVs (28 MB) 1.3 s, of which 0.7 s is the line loop.

Writing
    Coordinates are printed with ``%.9g``: 9 significant digits reproduce any value that was read
    from a file with at most 9 significant digits exactly (MakeHuman assets have 4-6 decimals) and
    keep other float64 values within 5e-9 relative, i.e. below 0.01 µm for a 2 m garment.
"""
from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np

from vfit_engine.errors import InputError
from vfit_engine.geometry import vertex_normals
from vfit_engine.io.atomic import atomic_write
from vfit_engine.io.meshdata import MAX_VERTS, MeshData

#: printf format of one coordinate (see the module docstring for why 9 digits).
FLOAT_FORMAT = "%.9g"

_WS = np.zeros(256, dtype=bool)
_WS[[9, 10, 11, 12, 13, 32]] = True


def _read_text(path):
    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        raise InputError(f"cannot read {path}: {exc.strerror or exc}") from None
    # utf-8-sig: a byte-order mark before the first line (Windows editors write one) is not part of it --
    # read as text it glued itself to the first "v", which was then dropped and every face shifted by one
    text = data.decode("utf-8-sig", errors="replace")
    if "\\" in text:
        text = re.sub(r"\\[ \t]*\r?\n", " ", text)
    return text


def _split_statements(lines):
    """Sort lines into v / vt / f bodies and remember g/o/usemtl/mtllib with their face index."""
    v, vt, f = [], [], []
    groups, objects, materials = [], [], []
    mtllib = None
    v_append, vt_append, f_append = v.append, vt.append, f.append
    for line in lines:
        if line.startswith("v "):
            v_append(line[2:])
        elif line.startswith("f "):
            f_append(line[2:])
        elif line.startswith("vt "):
            vt_append(line[3:])
        else:
            s = line.strip()
            if not s or s[0] == "#":
                continue
            parts = s.split(None, 1)
            key = parts[0]
            rest = parts[1].strip() if len(parts) > 1 else ""
            if key == "v":
                v_append(rest)
            elif key == "f":
                f_append(rest)
            elif key == "vt":
                vt_append(rest)
            elif key == "g":
                groups.append((rest, len(f)))
            elif key == "o":
                objects.append((rest, len(f)))
            elif key == "usemtl":
                materials.append((rest, len(f)))
            elif key == "mtllib":
                mtllib = rest
    return v, vt, f, groups, objects, materials, mtllib


def _statement_line(lines, key, k):
    """1-based line number of the k-th (0-based) statement ``key`` (slow path for messages)."""
    seen = -1
    for i, line in enumerate(lines):
        s = line.lstrip()
        if s.startswith(key) and (len(s) == len(key) or s[len(key)] in " \t"):
            seen += 1
            if seen == k:
                return i + 1
    return 0


def _fromstring(text, dtype):
    """C-speed parse of whitespace-separated numbers; None if any token is not a number."""
    with warnings.catch_warnings():
        # numpy signals unparsable trailing data with a DeprecationWarning: make it an error
        warnings.simplefilter("error", DeprecationWarning)
        try:
            return np.fromstring(text, dtype=dtype, sep=" ")
        except (ValueError, DeprecationWarning):
            return None


def _tokens_per_line(b, n_lines):
    """Byte positions of token starts and the number of tokens on each of ``n_lines`` lines."""
    ws = _WS[b]
    prev_ws = np.empty_like(ws)
    if ws.size:
        prev_ws[0] = True
        prev_ws[1:] = ws[:-1]
    starts = np.flatnonzero(~ws & prev_ws)
    # searchsorted on the sparse positions instead of cumsums over every byte (10x faster)
    tok_line = np.searchsorted(np.flatnonzero(b == 10), starts)
    return starts, tok_line, np.bincount(tok_line, minlength=n_lines)


def _parse_floats(bodies, ncols, path, lines, key):
    """Parse the first ``ncols`` numbers of each body; (len(bodies), ncols) float64."""
    text = "\n".join(bodies)
    _, _, counts = _tokens_per_line(np.frombuffer(text.encode("utf-8"), dtype=np.uint8), len(bodies))
    if np.all(counts == ncols):
        arr = _fromstring(text, np.float64)
        if arr is not None and arr.size == ncols * len(bodies):
            return arr.reshape(-1, ncols)
    # slow path: extra columns (w, vertex colours) or an error to locate
    out = np.empty((len(bodies), ncols), dtype=np.float64)
    for i, body in enumerate(bodies):
        parts = body.split()
        try:
            if len(parts) < ncols:
                raise ValueError
            out[i] = [float(p) for p in parts[:ncols]]
        except ValueError:
            line = _statement_line(lines, key, i)
            raise InputError(
                f"{path}:{line}: cannot read {key!r} line {key} {body.strip()[:60]!r}"
            ) from None
    return out


def _bad_face(path, lines, face, why):
    line = _statement_line(lines, "f", int(face))
    raise InputError(f"{path}:{line}: {why}")


def _parse_faces(bodies, path, lines):
    """Vectorised face parse: (offsets (m+1,), v (k,), vt (k,)) with raw 1-based/negative indices.

    vt is 0 where a corner has no texture index.
    """
    # "v//vn" -> "v/0/vn": 0 is not a valid OBJ index, so it marks "no vt"
    body = "\n".join(bodies).replace("//", "/0/")
    b = np.frombuffer(body.encode("utf-8"), dtype=np.uint8)
    starts, tok_line, counts = _tokens_per_line(b, len(bodies))
    ntok = int(starts.size)
    tok_of_slash = np.searchsorted(starts, np.flatnonzero(b == 47), side="right") - 1
    slashes = np.bincount(tok_of_slash, minlength=ntok)
    short = np.flatnonzero(counts < 3)
    if short.size:
        _bad_face(path, lines, short[0], "face with fewer than 3 vertices")
    if slashes.size and slashes.max() > 2:
        _bad_face(path, lines, tok_line[np.argmax(slashes > 2)], "cannot read face corner")
    nfields = slashes + 1
    try:
        nums = _fromstring(body.replace("/", " "), np.int64)
        if nums is None or nums.size != int(nfields.sum()):
            raise ValueError
    except ValueError:
        for i, fb in enumerate(bodies):
            for corner in fb.replace("//", "/0/").split():
                parts = corner.split("/")
                try:
                    [int(p) for p in parts]
                except ValueError:
                    _bad_face(path, lines, i, f"cannot read face corner {corner!r}")
        raise InputError(f"{path}: cannot read the faces") from None
    first = np.cumsum(nfields) - nfields
    vi = nums[first]
    vti = np.where(slashes >= 1, nums[np.minimum(first + 1, len(nums) - 1)], 0)
    offsets = np.zeros(len(bodies) + 1, dtype=np.int64)
    np.cumsum(counts, out=offsets[1:])
    return offsets, vi, vti


def _resolve(idx, n_before, n_total, path, lines, offsets, what, mask=None):
    """OBJ 1-based / negative indices -> 0-based; raise on 0 or out of range where ``mask``."""
    out = np.where(idx > 0, idx - 1, n_before + idx)
    bad = (idx == 0) | (out < 0) | (out >= n_total)
    if mask is not None:
        bad &= mask
    if bad.any():
        corner = int(np.argmax(bad))
        face = int(np.searchsorted(offsets, corner, side="right") - 1)
        _bad_face(path, lines, face, f"{what} index {int(idx[corner])} out of range (1..{n_total})")
    return out


def _count_before_faces(lines, key, n_faces):
    """For each face, how many ``key`` statements precede it (for negative indices)."""
    out = np.empty(n_faces, dtype=np.int64)
    n = 0
    k = 0
    for line in lines:
        s = line.lstrip()
        if s.startswith(key + " ") or s.startswith(key + "\t"):
            n += 1
        elif s.startswith("f ") or s.startswith("f\t"):
            out[k] = n
            k += 1
    return out


def read_obj(path, max_verts=MAX_VERTS):
    """Read an OBJ file; see the module docstring for what is kept.

    Parameters
    ----------
    path : str or Path
    max_verts : int
        More ``v`` lines than this raise InputError.

    Returns
    -------
    MeshData
        In the file's units.

    Raises
    ------
    InputError
        Unreadable file, no vertices, too many vertices, an unparsable number or a face index out
        of range; the message names the file and line.
    """
    text = _read_text(path)
    lines = text.splitlines()
    vb, vtb, fb, groups, objects, materials, mtllib = _split_statements(lines)
    if not vb:
        raise InputError(f"{path}: no vertices ('v' lines)")
    if len(vb) > max_verts:
        raise InputError(f"{path}: {len(vb)} vertices, more than the limit of {max_verts}")
    verts = _parse_floats(vb, 3, path, lines, "v")
    uvs = _parse_floats(vtb, 2, path, lines, "vt") if vtb else None

    if fb:
        offsets, vi, vti = _parse_faces(fb, path, lines)
    else:
        offsets, vi, vti = np.zeros(1, np.int64), np.zeros(0, np.int64), np.zeros(0, np.int64)
    nv, nvt = len(vb), len(vtb)
    sizes = np.diff(offsets)
    nv_before = nv
    if (vi < 0).any():
        nv_before = np.repeat(_count_before_faces(lines, "v", len(fb)), sizes)
    face_verts = _resolve(vi, nv_before, nv, path, lines, offsets, "vertex")
    face_uvs = None
    has_vt = vti != 0
    if has_vt.any():
        nvt_before = nvt
        if (vti < 0).any():
            nvt_before = np.repeat(_count_before_faces(lines, "vt", len(fb)), sizes)
        resolved = _resolve(vti, nvt_before, nvt, path, lines, offsets, "texture", mask=has_vt)
        face_uvs = np.where(has_vt, resolved, -1).astype(np.int64)
    return MeshData(
        verts=np.ascontiguousarray(verts),
        face_offsets=offsets,
        face_verts=np.ascontiguousarray(face_verts, dtype=np.int64),
        uvs=uvs,
        face_uvs=face_uvs,
        groups=groups,
        objects=objects,
        materials=materials,
        mtllib=mtllib,
    )


def _face_lines(mesh, lo, hi, normals=False):
    """Text of faces lo..hi-1 (1-based indices, ``v/vt`` where every corner of a face has a vt; with
    ``normals`` ``v/vt/vn`` and ``v//vn``, the normal of a vertex having its index)."""
    o = mesh.face_offsets
    fv = mesh.face_verts[o[lo]:o[hi]] + 1
    sizes = np.diff(o[lo:hi + 1])
    if mesh.face_uvs is not None and mesh.uvs is not None:
        fu = mesh.face_uvs[o[lo]:o[hi]]
        face_has_uv = np.minimum.reduceat(fu, o[lo:hi] - o[lo]) >= 0 if hi > lo else np.zeros(0, bool)
    else:
        fu = None
        face_has_uv = np.zeros(hi - lo, dtype=bool)
    if hi == lo:
        return ""
    s = int(sizes[0])
    if np.all(sizes == s) and (face_has_uv.all() or not face_has_uv.any()):
        # uniform block: one printf template for all faces
        if face_has_uv.all():
            vals = np.stack([fv, fu + 1] + [fv] * normals, axis=1).ravel()
            template = "f" + (" %d/%d/%d" if normals else " %d/%d") * s + "\n"
        else:
            vals = np.stack([fv] * (1 + normals), axis=1).ravel()
            template = "f" + (" %d//%d" if normals else " %d") * s + "\n"
        return (template * (hi - lo)) % tuple(vals.tolist())
    out = []
    rel = o[lo:hi + 1] - o[lo]
    for i in range(hi - lo):
        a, b = rel[i], rel[i + 1]
        n = "/{}" if normals else ""
        if face_has_uv[i]:
            corners = zip(fv[a:b].tolist(), fu[a:b].tolist())
            out.append("f " + " ".join(f"{x}/{t + 1}" + n.format(x) for x, t in corners) + "\n")
        else:
            out.append("f " + " ".join(f"{x}/" + n.format(x) if normals else str(x) for x in fv[a:b].tolist())
                       + "\n")
    return "".join(out)


def _floats_block(prefix, arr):
    ncols = arr.shape[1]
    template = prefix + (" " + FLOAT_FORMAT) * ncols + "\n"
    return (template * arr.shape[0]) % tuple(arr.ravel().tolist())


def format_obj(mesh, header=None, mtllib=True, normals=True):
    """The OBJ text of ``mesh`` (see ``write_obj``)."""
    parts = []
    if header:
        for line in [header] if isinstance(header, str) else header:
            for sub in str(line).splitlines() or [""]:
                parts.append(f"# {sub}\n")
    if mtllib and mesh.mtllib:
        parts.append(f"mtllib {mesh.mtllib}\n")
    verts = np.asarray(mesh.verts, dtype=np.float64)
    if not np.all(np.isfinite(verts)):
        raise InputError("refusing to write a mesh with NaN or infinite coordinates")
    parts.append(_floats_block("v", verts))
    if mesh.uvs is not None and len(mesh.uvs):
        parts.append(_floats_block("vt", np.asarray(mesh.uvs, dtype=np.float64)))
    normals = bool(normals and mesh.n_faces)
    if normals:
        parts.append(_floats_block("vn", vertex_normals(verts, mesh.face_verts, mesh.face_offsets)))
    events = sorted(
        [(first, 0, f"o {name}\n") for name, first in mesh.objects]
        + [(first, 1, f"g {name}\n") for name, first in mesh.groups]
        + [(first, 2, f"usemtl {name}\n") for name, first in mesh.materials],
        key=lambda e: (e[0], e[1]),
    )
    lo = 0
    for first, _, line in events:
        first = min(max(int(first), lo), mesh.n_faces)
        parts.append(_face_lines(mesh, lo, first, normals))
        parts.append(line)
        lo = first
    parts.append(_face_lines(mesh, lo, mesh.n_faces, normals))
    return "".join(parts)


def write_obj(path, mesh, header=None, mtllib=True, normals=True):
    """Write ``mesh`` as OBJ atomically: ``v`` (``%.9g``), ``vt``, ``vn`` (area-weighted vertex normals, one
    per vertex: viewers shade it smooth), ``f v/vt/vn``, and the input's o/g/usemtl names.

    Parameters
    ----------
    path : str or Path
    mesh : MeshData
    header : str or list of str or None
        Comment lines at the top.
    mtllib : bool
        Pass ``mesh.mtllib`` through as an ``mtllib`` line (the .mtl itself is not copied).
    normals : bool
        Write ``vn`` lines and reference them from the faces.
    """
    text = format_obj(mesh, header=header, mtllib=mtllib, normals=normals)
    with atomic_write(path, "w") as f:
        f.write(text)
