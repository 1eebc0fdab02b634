"""Garment openings (hems, cuffs, waistbands, necklines) against the body part they go round.

An opening is a closed boundary loop of the garment mesh. Where it encircles a body part (an
arm, a leg, the waist), the shortest loop that goes round that part is at least the perimeter of
the convex hull of the part's cross-section (a tape measure round it), plus ``2 pi skin`` for
the clearance the collider keeps. If the opening's rest length is shorter than that at its place
and a few centimetres either side along the part, the garment cannot be worn there without
stretching the opening by at least::

    required_strain = (min tape + 2 pi skin) / rest length - 1

which no drape can avoid: the figure bounds the strain any result must show (the MakeHuman
female suits' short sleeves, for one, are 214 and 225 mm round against >= 238 mm of arm).
The cross-sections are cut in the plane that fits the opening best (least squares), with the
body rotated so that plane is horizontal for :class:`vfit_engine.section.MeshSections`.
"""
from __future__ import annotations

import numpy as np

from vfit_engine.geometry import closed_loops, winding_number


def _hull_perimeter(p):
    from scipy.spatial import ConvexHull

    if len(p) < 3:
        return 0.0
    try:
        return float(ConvexHull(p).area)  # in 2-D, "area" is the perimeter
    except Exception:  # degenerate (collinear) section
        return 0.0


def check_openings(mesh, body_verts, body_tris, skin=0.002, offsets=(-0.03, -0.02, -0.01, 0.0, 0.01, 0.02, 0.03),
                   pos=None):
    """Each closed opening of the garment against the body part it encircles.

    Parameters
    ----------
    mesh : MeshData
        The garment; its vertices give the openings' rest lengths.
    pos : (n, 3) float64 m or None
        Where the garment is put on the body (default ``mesh.verts``).
    body_verts : (N, 3) float64, m;  body_tris : (T, 3) int64
    skin : float, m
        Clearance kept from the body.
    offsets : sequence of float, m
        Shifts of the cutting plane along its normal; the smallest tape over them is used.

    Returns
    -------
    list of dict
        One per opening that encircles a body part: ``indices`` ((L,) int64, the loop),
        ``vertices`` (count), ``centre_m`` (3,), ``rest_length_mm``, ``body_tape_mm`` (smallest over
        ``offsets``), ``required_strain`` (fraction, <= 0 when the opening fits).
    """
    from vfit_engine.section import MeshSections, rotation_to_y

    rest = mesh.verts
    pos = rest if pos is None else np.asarray(pos, dtype=np.float64)
    body = np.ascontiguousarray(body_verts, dtype=np.float64)
    sections = MeshSections(body_tris, body.shape[0])
    out = []
    for loop in closed_loops(mesh):
        p = pos[loop]
        centre = p.mean(axis=0)
        _, _, vt = np.linalg.svd(p - centre)
        rot = rotation_to_y(vt[2])
        rb = body @ rot.T
        c2 = rot @ centre
        q = (p - centre) @ rot.T  # the opening in the plane's frame (y ~ 0)
        reach = float(np.max(np.linalg.norm(q[:, [0, 2]], axis=1)))
        tapes = []
        for off in offsets:
            for sec in sections.loops(rb, c2[1] + off):
                # the body loop this opening goes round: it winds round the opening's centre and
                # lies within its reach (not the torso round an arm's cuff)
                if len(sec) < 3 or np.max(np.linalg.norm(sec - c2[[0, 2]], axis=1)) > 1.5 * reach:
                    continue
                if abs(winding_number(sec, c2[[0, 2]])) > 0.5:
                    tapes.append(_hull_perimeter(sec))
        if not tapes:
            continue
        tape = min(tapes)
        length = float(np.linalg.norm(rest[loop] - np.roll(rest[loop], -1, axis=0), axis=1).sum())
        need = (tape + 2.0 * np.pi * skin) / length - 1.0 if length > 0 else 0.0
        out.append(dict(indices=loop, vertices=int(loop.size), centre_m=[float(v) for v in centre],
                        rest_length_mm=1000.0 * length, body_tape_mm=1000.0 * tape, required_strain=float(need)))
    return out
