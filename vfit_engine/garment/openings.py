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


def boundary_loops(face_verts, face_offsets):
    """Closed boundary loops of a polygon mesh, as vertex index arrays in walk order.

    Parameters
    ----------
    face_verts : (k,) int64;  face_offsets : (m + 1,) int64

    Returns
    -------
    list of (L,) int64
        Only loops where every vertex has exactly two boundary edges (simple closed loops).
    """
    fv = np.asarray(face_verts, dtype=np.int64)
    fo = np.asarray(face_offsets, dtype=np.int64)
    sizes = np.diff(fo)
    face_of = np.repeat(np.arange(sizes.size), sizes)
    nxt = fv[fo[face_of] + (np.arange(fv.size) - fo[face_of] + 1) % sizes[face_of]]
    edges = np.sort(np.stack([fv, nxt], axis=1), axis=1)
    uniq, count = np.unique(edges, axis=0, return_counts=True)
    bd = uniq[count == 1]
    nbrs = {}
    for a, b in bd:
        nbrs.setdefault(int(a), []).append(int(b))
        nbrs.setdefault(int(b), []).append(int(a))
    seen, loops = set(), []
    for start, adj in nbrs.items():
        if start in seen or len(adj) != 2:
            continue
        loop, prev, cur, ok = [start], -1, start, True
        seen.add(start)
        while True:
            cand = [w for w in nbrs[cur] if w != prev]
            if len(nbrs[cur]) != 2 or not cand:
                ok = False
                break
            prev, cur = cur, cand[0]
            if cur == start:
                break
            if cur in seen:
                ok = False
                break
            loop.append(cur)
            seen.add(cur)
        if ok and len(loop) >= 3:
            loops.append(np.array(loop, dtype=np.int64))
    return loops


def _rotation_to_y(n):
    """(3, 3) rotation taking unit vector ``n`` to +Y."""
    y = np.array([0.0, 1.0, 0.0])
    v = np.cross(n, y)
    c = float(np.dot(n, y))
    if np.linalg.norm(v) < 1e-12:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    vx = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + vx + vx @ vx / (1.0 + c)


def _hull_perimeter(p):
    from scipy.spatial import ConvexHull

    if len(p) < 3:
        return 0.0
    try:
        return float(ConvexHull(p).area)  # in 2-D, "area" is the perimeter
    except Exception:  # degenerate (collinear) section
        return 0.0


def check_openings(garment_pos, face_verts, face_offsets, body_verts, body_tris, skin=0.002,
                   offsets=(-0.03, -0.02, -0.01, 0.0, 0.01, 0.02, 0.03), rest_pos=None):
    """Each closed opening of the garment against the body part it encircles.

    Parameters
    ----------
    garment_pos : (n, 3) float64, m
        The garment where it is put on the body.
    face_verts : (k,) int64;  face_offsets : (m + 1,) int64
    body_verts : (N, 3) float64, m;  body_tris : (T, 3) int64
    skin : float, m
        Clearance kept from the body.
    offsets : sequence of float, m
        Shifts of the cutting plane along its normal; the smallest tape over them is used.
    rest_pos : (n, 3) float64 m or None
        Where the opening's rest length is measured (default ``garment_pos``).

    Returns
    -------
    list of dict
        One per opening that encircles a body part: ``indices`` ((L,) int64, the loop),
        ``vertices`` (count), ``centre_m`` (3,), ``rest_length_mm``, ``body_tape_mm`` (smallest over
        ``offsets``), ``required_strain`` (fraction, <= 0 when the opening fits).
    """
    from vfit_engine.section import MeshSections

    pos = np.asarray(garment_pos, dtype=np.float64)
    rest = pos if rest_pos is None else np.asarray(rest_pos, dtype=np.float64)
    body = np.ascontiguousarray(body_verts, dtype=np.float64)
    sections = MeshSections(body_tris, body.shape[0])
    out = []
    for loop in boundary_loops(face_verts, face_offsets):
        p = pos[loop]
        centre = p.mean(axis=0)
        _, _, vt = np.linalg.svd(p - centre)
        rot = _rotation_to_y(vt[2])
        rb = body @ rot.T
        c2 = rot @ centre
        q = (p - centre) @ rot.T  # the opening in the plane's frame (y ~ 0)
        reach = float(np.max(np.linalg.norm(q[:, [0, 2]], axis=1)))
        tapes = []
        for off in offsets:
            for sec in sections.loops(rb, c2[1] + off):
                d = sec - c2[[0, 2]]
                # the body loop this opening goes round: its points lie within the opening's reach
                # and it surrounds the opening's centre (winding test on the convex side is enough:
                # the centre is inside the loop's bounding box and close to its centroid)
                if np.max(np.linalg.norm(d, axis=1)) > 1.5 * reach:
                    continue
                lo, hi = sec.min(axis=0), sec.max(axis=0)
                inside = np.all(c2[[0, 2]] > lo) and np.all(c2[[0, 2]] < hi)
                if inside and len(sec) >= 3:
                    tapes.append(_hull_perimeter(sec))
        if not tapes:
            continue
        tape = min(tapes)
        length = float(np.linalg.norm(rest[loop] - np.roll(rest[loop], -1, axis=0), axis=1).sum())
        need = (tape + 2.0 * np.pi * skin) / length - 1.0 if length > 0 else 0.0
        out.append(dict(indices=loop, vertices=int(loop.size), centre_m=[float(v) for v in centre],
                        rest_length_mm=1000.0 * length, body_tape_mm=1000.0 * tape, required_strain=float(need)))
    return out
