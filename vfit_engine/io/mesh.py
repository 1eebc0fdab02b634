"""The format-dispatching ``read_mesh`` / ``write_mesh`` (OBJ, PLY; GLB written only).

The mesh type they read and write, :class:`~vfit_engine.io.meshdata.MeshData`, lives in
:mod:`vfit_engine.io.meshdata`, below the readers, so every layer can use it without importing them.
"""
from __future__ import annotations

from pathlib import Path

from vfit_engine.errors import InputError
from vfit_engine.io.gltf import ScenePart, write_scene_glb
from vfit_engine.io.meshdata import MAX_VERTS
from vfit_engine.io.obj import read_obj, write_obj
from vfit_engine.io.ply import read_ply, write_ply

#: Mesh formats, by file extension: ``read_mesh`` reads obj and ply, ``write_mesh`` writes all three.
FORMATS = ("obj", "ply", "glb")


def _ext(path):
    return Path(path).suffix.lower()


def read_mesh(path, max_verts=MAX_VERTS):
    """Read an OBJ or PLY mesh keeping vertex order, faces and UVs.

    Parameters
    ----------
    path : str or Path
    max_verts : int
        More vertices than this raise InputError.

    Returns
    -------
    MeshData
        In the file's units.
    """
    ext = _ext(path)
    if ext == ".obj":
        return read_obj(path, max_verts=max_verts)
    if ext == ".ply":
        return read_ply(path, max_verts=max_verts)
    raise InputError(f"{path}: unknown mesh format {ext or '(no extension)'!r}, expected .obj or .ply")


def write_mesh(path, mesh, verts=None, header=None):
    """Write ``mesh`` (optionally with replacement positions ``verts`` (n, 3)) atomically.

    Parameters
    ----------
    path : str or Path
        ``.obj``, ``.ply`` or ``.glb`` (write-only: a glTF scene for viewers; the header is not kept).
    mesh : MeshData
    verts : (n, 3) array_like or None
        Positions to write instead of ``mesh.verts`` (same count and order).
    header : str or list of str or None
        Comment lines written at the top of the file.
    """
    ext = _ext(path)
    if verts is not None:
        mesh = mesh.with_verts(verts)
    if ext == ".obj":
        return write_obj(path, mesh, header=header)
    if ext == ".ply":
        return write_ply(path, mesh, header=header)
    if ext == ".glb":
        # a one-mesh glTF scene (UVs kept; vertices split at UV seams, see vfit_engine.io.gltf)
        return write_scene_glb(path, [ScenePart(Path(path).stem, mesh)])
    raise InputError(f"{path}: unknown mesh format {ext or '(no extension)'!r}, expected .obj, .ply or .glb")
