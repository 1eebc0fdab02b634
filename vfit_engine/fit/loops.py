"""A garment's loops round the body in a plane: its girth (a tape round the draped garment), the steps of its
line across the cloth's triangles, and how far that line is stretched (:mod:`vfit_engine.fit.table` reads them
for each region of the fit table; :mod:`vfit_engine.fit.pattern_fit` for a sewn pattern's panels)."""
from __future__ import annotations

import numpy as np
from scipy.spatial import ConvexHull

from vfit_engine.geometry import winding_number

def hull_of(points_xz):
    """Convex hull of (k, 2) points: (hull points (h, 2), perimeter m, equations (h, 3)) or None."""
    if len(points_xz) < 3:
        return None
    try:
        h = ConvexHull(points_xz)
    except Exception:  # collinear
        return None
    return points_xz[h.vertices], float(h.area), h.equations


def _distance_to_loop(points, loop):
    """(k,) distance (m) of each of ``points`` (k, 2) from the closed polygon ``loop`` (m, 2)."""
    a = loop
    d = np.roll(loop, -1, axis=0) - a
    t = np.einsum("kmj,mj->km", points[:, None, :] - a, d) / np.maximum(np.einsum("mj,mj->m", d, d), 1e-18)
    near = a + np.clip(t, 0.0, 1.0)[..., None] * d
    return np.linalg.norm(points[:, None, :] - near, axis=2).min(axis=1)


def round_together(loops, closed, centre, others):
    """Whether a closed garment loop winds round ``centre`` and round the middle of one of the body's ``others``
    loops too (a skirt's hem round both thighs)."""
    middles = [o.mean(axis=0) for o in others if len(o)]
    for loop, shut in zip(loops, closed if closed is not None else [True] * len(loops)):
        if shut and len(loop) >= 3 and abs(winding_number(loop, centre)) > 0.5 and any(
                abs(winding_number(loop, m)) > 0.5 for m in middles):
            return True
    return False


def garment_girth(loops, centre, own, others=(), reach=np.inf, closed=None):
    """The tape round a garment's own loop round a body part, in the part's plane.

    Of the garment's section loops that wind round ``centre`` (a sleeve beside the torso does not) and its
    open chains (a shirt whose sleeves are pieces of their own, cut through its armholes: a front and a back
    running out along the sleeves), the points within ``reach`` of it that lie nearer the body part's own
    loop than any of the body's other loops in the plane: where the plane cuts a shirt through its
    armholes, its loop runs out along the sleeves and round the arms, no part of the chest; where an upper
    arm's plane cuts the shirt's side, the torso's cloth is no part of the sleeve. The tape is the
    perimeter of their convex hull, over the outside of the cloth as the body's tape goes over its skin.

    Parameters
    ----------
    loops : list of (k, 2) float arrays, m
        The garment's section loops in the plane (its horizontal frame, as ``MeshSections.loops`` gives).
    centre : (2,) float, m
        A point inside the body part's loop.
    own : (m, 2) float, m
        The body part's own loop in the plane (the torso, an arm, a thigh, the neck).
    others : list of (m_i, 2) float arrays, m
        The body's other loops in the plane (the arms beside the torso, the torso beside an arm).
    reach : float, m
    closed : list of bool or None
        Per loop, whether it is closed (None: all are).

    Returns
    -------
    (points (h, 2), perimeter m, equations (h, 3)) or None
        The convex hull; None when no garment loop goes round the part or what is left of them does not
        enclose ``centre``.
    """
    centre = np.asarray(centre, dtype=np.float64)
    kept = []
    for loop, shut in zip(loops, closed if closed is not None else [True] * len(loops)):
        if len(loop) < 2 or (shut and (len(loop) < 3 or abs(winding_number(loop, centre)) <= 0.5)):
            continue
        loop = loop[np.linalg.norm(loop - centre, axis=1) <= reach]
        if len(loop) and len(others):
            mine = _distance_to_loop(loop, own)
            loop = loop[mine <= np.min([_distance_to_loop(loop, o) for o in others], axis=0)]
        kept.append(loop)
    hull = hull_of(np.concatenate(kept)) if kept else None
    if hull is None or np.any(hull[2][:, :2] @ centre + hull[2][:, 2] > 0.0):
        return None
    return hull


def _cut_loops(tris, heights):
    """The loops and open chains in which the level ``heights == 0`` cuts a triangle mesh: per loop, the
    (k, 2) int edges it crosses in walk order (each two in a row share a triangle) and whether it is closed.
    ``heights`` (n,): every vertex's signed height over the plane."""
    up = heights > 0.0
    e = np.stack([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]], axis=1)  # (T, 3, 2)
    cut = up[e[..., 0]] != up[e[..., 1]]
    two = cut.sum(axis=1) == 2
    if not two.any():
        return []
    pairs = np.sort(e[two][cut[two]].reshape(-1, 2, 2), axis=2)  # (t, 2 edges, 2 verts)
    keys, inv = np.unique(pairs.reshape(-1, 2), axis=0, return_inverse=True)
    nbr = [[] for _ in range(len(keys))]
    for a, b in inv.reshape(-1, 2):
        nbr[a].append(b)
        nbr[b].append(a)
    seen = np.zeros(len(keys), dtype=bool)
    out = []
    # the chains first, from their ends (a mesh boundary), then the loops
    for start in sorted(range(len(keys)), key=lambda k: len(nbr[k]) != 1):
        if seen[start] or len(nbr[start]) > 2:
            continue
        walk, prev, cur = [start], -1, start
        seen[start] = True
        while True:
            nxt = [n for n in nbr[cur] if n != prev and not seen[n]]
            if len(nbr[cur]) > 2 or not nxt:
                break
            prev, cur = cur, nxt[0]
            seen[cur] = True
            walk.append(cur)
        shut = len(nbr[start]) == 2 and start in nbr[cur] and len(walk) >= 3
        if len(walk) >= 2:
            out.append((keys[walk], shut))
    return out


def loop_steps(tris, rest, pos, plane, own, others=(), reach=np.inf):
    """The steps of the garment's line round a body part in ``plane`` (:func:`loop_strain`).

    Returns
    -------
    (draped (k,), made (k,), vertex (k,)) or None
        Each kept step's length draped (at ``pos``) and as made (``rest``), m, and a vertex of the triangle it
        crosses (its cloth: a pattern's panel); None where no step is kept.
    """
    q = pos @ plane.rot.T
    centre = plane.centre_xz
    draped, made, vertex = [], [], []
    for loop, shut in _cut_loops(tris, q[:, 1] - plane.height):
        a, b = loop[:, 0], loop[:, 1]
        t = ((q[a, 1] - plane.height) / (q[a, 1] - q[b, 1]))[:, None]
        xz = q[a][:, [0, 2]] + t * (q[b][:, [0, 2]] - q[a][:, [0, 2]])
        if shut and abs(winding_number(xz, centre)) <= 0.5:
            continue
        keep = np.linalg.norm(xz - centre, axis=1) <= reach
        if len(others):
            keep &= _distance_to_loop(xz, own) <= np.min([_distance_to_loop(xz, o) for o in others], axis=0)
        step = keep & np.roll(keep, -1)
        if not shut:
            step[-1] = False  # no step from a chain's end back to its start
        r = rest[a] + t * (rest[b] - rest[a])
        draped.append(np.linalg.norm(np.roll(xz, -1, axis=0) - xz, axis=1)[step])
        made.append(np.linalg.norm(np.roll(r, -1, axis=0) - r, axis=1)[step])
        vertex.append(a[step])  # the step from crossing i to i + 1 runs through a triangle with edge i
    if not made or np.sum([m.sum() for m in made]) <= 0.0:
        return None
    return np.concatenate(draped), np.concatenate(made), np.concatenate(vertex)


def loop_strain(tris, rest, pos, plane, own, others=(), reach=np.inf, steps=None):
    """How far the garment is stretched round a body part along its tape's line.

    The garment's section in the plane (at ``pos``), its loops round the part, its open chains and their
    points nearer the part's own body loop than its other loops, as :func:`garment_girth` keeps them: each step between two
    kept points in a row crosses one triangle, whose rest shape (``rest``) gives that step's length as
    made (:func:`loop_steps`; ``steps``: its answer, when the caller has it).

    Returns
    -------
    (stretch, ratio) or None
        ``stretch``: draped length / rest length - 1 over the steps under tension (cloth cannot carry a
        compression: a step shorter than made has buckled into a fold, bunched at a seam, and carries
        nothing round the body); over all steps where none is. ``ratio``: draped / rest length over all
        steps (the garment as made is the draped girth / ``ratio``). None where no step is kept.
    """
    steps = loop_steps(tris, rest, pos, plane, own, others, reach) if steps is None else steps
    if steps is None:
        return None
    draped, made = steps[0], steps[1]
    taut = draped >= made
    ratio = float(draped.sum() / made.sum())
    stretch = float(draped[taut].sum() / made[taut].sum()) - 1.0 if taut.any() else ratio - 1.0
    return stretch, ratio
