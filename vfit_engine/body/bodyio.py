"""Reading and writing bodies with hm08 topology (OBJ with UVs, or PLY), in metres, Y up."""
from __future__ import annotations

import numpy as np

from vfit_engine.body.model import N_BODY, N_VERTS, BodyModel
from vfit_engine.errors import InputError
from vfit_engine.io.mesh import read_mesh, write_mesh
from vfit_engine.io.meshdata import mesh_from_faces
from vfit_engine.units import LENGTH_UNITS, guess_length_unit


def body_mesh(model: BodyModel, verts: np.ndarray):
    """MeshData of the visible body: the 13,380 body vertices in hm08 order, its quads and UVs."""
    return mesh_from_faces(np.asarray(verts, dtype=np.float64)[:N_BODY], model.body_quads,
                           uvs=model.uvs, face_uvs=model.body_quad_uvs)


def write_body(path, model: BodyModel, verts: np.ndarray, header: str | None = None) -> None:
    """Write the body to ``path`` (.obj with UVs, or .ply), metres, atomically."""
    write_mesh(path, body_mesh(model, verts), header=header)


#: Heights (m) a body read in an explicit unit may have.
BODY_HEIGHT_RANGE_M = (0.5, 3.0)


def read_body(path, model: BodyModel, units: str = "auto") -> tuple[np.ndarray, str]:
    """Read a mesh with hm08 body topology and return its body vertices in metres.

    Accepts vfit's own output and MakeHuman exports: 13,380 vertices (body only)
    or 19,158 (with helpers), faces as quads or triangulated. Another topology
    raises InputError saying so.

    Returns
    -------
    verts : (13380, 3) float64, m
    units : str
        The unit the file was read in (``units`` or the one guessed from its height).
    """
    mesh = read_mesh(path)
    n = mesh.n_verts
    if n not in (N_BODY, N_VERTS):
        raise InputError(f"{path}: {n} vertices is not hm08 body topology (expected {N_BODY} or {N_VERTS})")
    if not np.isfinite(mesh.verts).all():
        raise InputError(f"{path}: vertices contain NaN or infinite coordinates")
    # every edge of the hm08 body quads must be an edge of the file (triangulation may add diagonals)
    fe = mesh.edges()
    have = set((fe[:, 0] * N_VERTS + fe[:, 1]).tolist())
    q = model.body_quads
    be = np.sort(np.concatenate([q[:, [0, 1]], q[:, [1, 2]], q[:, [2, 3]], q[:, [3, 0]]]), axis=1)
    missing = np.count_nonzero(~np.isin(be[:, 0] * N_VERTS + be[:, 1], np.fromiter(have, np.int64)))
    if missing:
        raise InputError(f"{path}: not hm08 body topology ({missing} of the body's edges are missing)")
    verts = mesh.verts[:N_BODY]
    height = float(np.ptp(verts[:, 1]))
    if not height > 0:  # (guessing its units would ask for --units, which vfit drape uses for the garment)
        raise InputError(f"{path}: the body is flat (all its vertices at one height): not a body mesh")
    guess = guess_length_unit(height, expected_m=1.65)
    lo, hi = BODY_HEIGHT_RANGE_M
    if units == "auto":
        units = guess
        if not lo <= height * LENGTH_UNITS[units] <= hi:
            raise InputError(f"{path}: the body is {height:.3g} file units tall, not a human body in any unit "
                             f"({lo:g}-{hi:g} m)")
    elif units not in LENGTH_UNITS:
        raise InputError(f"unknown units {units!r}; use one of auto, {', '.join(LENGTH_UNITS)}")
    elif not lo <= height * LENGTH_UNITS[units] <= hi:
        # an explicit unit that makes the body 16 m or 2 cm tall is a mistake, not a choice to honour
        raise InputError(f"{path}: the body is {height * LENGTH_UNITS[units]:.3g} m tall read in {units}, not a "
                         f"human body ({lo:g}-{hi:g} m); its height says {guess}: give --units {guess} or "
                         "--units auto")
    return np.ascontiguousarray(verts * LENGTH_UNITS[units]), units
