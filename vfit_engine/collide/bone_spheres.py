"""Spheres along the skeleton, radii from the body's local sections.

The skeleton variant of the sphere collider (the issue's "a configurable number along the
skeleton, radii from the local sections"), to compare with the greedy medial cover of
:mod:`vfit_engine.collide.auto_spheres`.

Method
------
For every bone ``(head, tail)`` and ``k = 0 .. per_bone - 1``:

1. the centre is ``p = head + t (tail - head)`` with ``t = (k + 1/2) / per_bone``;
2. the body is cut by the plane through ``p`` perpendicular to the bone (the body is rotated so
   the bone runs along +Y and :class:`vfit_engine.section.MeshSections` cuts it at ``y = p_y``);
3. ``p`` must lie inside the section (even-odd rule over all loops of the plane); otherwise the
   sphere is skipped. The loop that carries it is the innermost loop containing ``p``;
4. the radius is

   * ``"inscribed"``: the distance from ``p`` to the nearest section segment (any loop: a loop
     outside the carrying one is farther than the carrying one, a hole inside it may be
     nearer), ``r = min_i dist(p, s_i)``;
   * ``"mean"``: the radius of the circle of the carrying loop's perimeter, ``r = L / (2 pi)``;

5. spheres with ``r < min_radius`` are dropped.

A section is a plane property: near a bone's end, where the body tapers along the bone, the
in-plane distance can exceed the 3-D distance to the surface. ``clamp=True`` (default for
``"inscribed"``) therefore also caps the radius by the exact 3-D distance from ``p`` to the body
triangles, so an inscribed sphere lies inside the body.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from vfit_engine.body.segment import bone_positions, seed_bones
from vfit_engine.errors import InputError
from vfit_engine.section import MeshSections, rotation_to_y

#: Radius rules accepted by :func:`fit_bone_spheres`.
RADIUS_RULES = ("inscribed", "mean")

#: Bones shorter than this are left out by :func:`skeleton_bones`, m.
MIN_BONE_LENGTH = 0.01


def skeleton_bones(model, verts, min_length=MIN_BONE_LENGTH):
    """Head and tail of the bones of the 17 body parts on a shaped body.

    Parameters
    ----------
    model : BodyModel
    verts : (19158, 3) float64, m
        All vertices, helpers included (the joint cubes place the bones).
    min_length : float, m
        Bones shorter than this are skipped.

    Returns
    -------
    list of (head (3,) float64 m, tail (3,) float64 m)
        In the order of :func:`vfit_engine.body.segment.seed_bones` (part by part).
    """
    pos = bone_positions(model, verts)
    chosen = [b for _part, names in seed_bones(model).items() for b in names]
    out = []
    for b in chosen:
        head, tail = (np.asarray(x, dtype=np.float64) for x in pos[b])
        if np.linalg.norm(tail - head) >= min_length:
            out.append((head, tail))
    return out


def _crossings(q, loop):
    """Number of edges of the closed polygon ``loop`` (k, 2) crossed by the ray from ``q`` along +x."""
    a = loop
    b = np.roll(loop, -1, axis=0)
    straddle = (a[:, 1] > q[1]) != (b[:, 1] > q[1])
    if not straddle.any():
        return 0
    a, b = a[straddle], b[straddle]
    x = a[:, 0] + (q[1] - a[:, 1]) * (b[:, 0] - a[:, 0]) / (b[:, 1] - a[:, 1])
    return int(np.count_nonzero(x > q[0]))


def _segment_distance(q, loop):
    """Smallest distance (m) from ``q`` (2,) to the edges of the closed polygon ``loop`` (k, 2)."""
    a = loop
    e = np.roll(loop, -1, axis=0) - a
    w = q - a
    ee = np.einsum("ij,ij->i", e, e)
    t = np.clip(np.einsum("ij,ij->i", w, e) / np.where(ee > 0.0, ee, 1.0), 0.0, 1.0)
    return float(np.sqrt(np.min(np.einsum("ij,ij->i", w - t[:, None] * e, w - t[:, None] * e))))


def _perimeter(loop):
    return float(np.sum(np.linalg.norm(np.roll(loop, -1, axis=0) - loop, axis=1)))


def _section_radius(q, loops, rule):
    """Radius at the in-plane point ``q`` from the plane's loops, or None when ``q`` is outside."""
    if not loops:
        return None
    counts = [_crossings(q, lp) for lp in loops]
    if sum(counts) % 2 == 0:
        return None
    if rule == "inscribed":
        return min(_segment_distance(q, lp) for lp in loops)
    # innermost containing loop: the smallest one that contains q on its own
    inside = [i for i, c in enumerate(counts) if c % 2 == 1]
    areas = []
    for i in inside:
        x, z = loops[i][:, 0], loops[i][:, 1]
        areas.append(abs(0.5 * float(np.dot(x, np.roll(z, -1)) - np.dot(z, np.roll(x, -1)))))
    return _perimeter(loops[inside[int(np.argmin(areas))]]) / (2.0 * np.pi)


def _point_triangle_distance(p, a, b, c):
    """Distance (m) from point ``p`` (3,) to each triangle ``(a, b, c)`` (each (k, 3)).

    Ericson, Real-Time Collision Detection (2005), 5.1.5: the closest point lies in the
    Voronoi region of a vertex, an edge or the face, told apart by the barycentric signs.
    """
    ab, ac, ap = b - a, c - a, p - a
    bp, cp = p - b, p - c
    dot = lambda u, w: np.einsum("ij,ij->i", u, w)  # noqa: E731
    d1, d2 = dot(ab, ap), dot(ac, ap)
    d3, d4 = dot(ab, bp), dot(ac, bp)
    d5, d6 = dot(ab, cp), dot(ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        den = va + vb + vc
        v_face, w_face = vb / den, vc / den
        t_ab = d1 / (d1 - d3)
        t_ac = d2 / (d2 - d6)
        t_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
    q = a + v_face[:, None] * ab + w_face[:, None] * ac
    # later assignments take precedence: face, then edges, then vertices (Ericson's test order reversed)
    on_bc = (va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0)
    q = np.where(on_bc[:, None], b + t_bc[:, None] * (c - b), q)
    on_ac = (vb <= 0) & (d2 >= 0) & (d6 <= 0)
    q = np.where(on_ac[:, None], a + t_ac[:, None] * ac, q)
    on_ab = (vc <= 0) & (d1 >= 0) & (d3 <= 0)
    q = np.where(on_ab[:, None], a + t_ab[:, None] * ab, q)
    q = np.where(((d6 >= 0) & (d5 <= d6))[:, None], c, q)
    q = np.where(((d3 >= 0) & (d4 <= d3))[:, None], b, q)
    q = np.where(((d1 <= 0) & (d2 <= 0))[:, None], a, q)
    return np.linalg.norm(p - q, axis=1)


class _SurfaceDistance:
    """Exact unsigned distance from points to a triangle mesh, searched near the vertices."""

    def __init__(self, verts, tris):
        self.verts, self.tris = verts, tris
        corners = verts[tris]
        edge = np.linalg.norm(corners - np.roll(corners, 1, axis=1), axis=2)
        # every point of a triangle lies within its longest edge of each of its corners
        self.reach = float(edge.max())
        self.tree = cKDTree(verts)
        order = np.argsort(tris.ravel(), kind="stable")
        self.vert_tris = np.split(order // 3, np.cumsum(np.bincount(tris.ravel(), minlength=len(verts)))[:-1])

    def below(self, p, bound):
        """min(bound, distance from p (3,) to the mesh), m."""
        # the nearest vertex bounds the distance from above, which keeps the search ball small
        bound = min(bound, float(self.tree.query(p)[0]))
        near = self.tree.query_ball_point(p, bound + self.reach)
        cand = np.unique(np.concatenate([self.vert_tris[i] for i in near]))
        t = self.tris[cand]
        d = _point_triangle_distance(p, self.verts[t[:, 0]], self.verts[t[:, 1]], self.verts[t[:, 2]])
        # a zero-area triangle gives NaN; its edges belong to its neighbours, which are measured
        return min(bound, float(np.min(np.where(np.isnan(d), np.inf, d))))


def fit_bone_spheres(body_verts, body_tris, bones, per_bone=4, radius="inscribed", min_radius=0.008, clamp=None):
    """Spheres along the bones, radii from the body section perpendicular to each bone.

    Parameters
    ----------
    body_verts : (n, 3) float, m
        The body (for hm08: the first 13,380 vertices), Y up.
    body_tris : (T, 3) int
        Outward-wound triangles of a closed manifold body (``BodyModel.body_tris``).
    bones : sequence of (head (3,), tail (3,)), m
        See :func:`skeleton_bones`. Zero-length bones are an InputError.
    per_bone : int
        Spheres per bone, at ``t = (k + 0.5) / per_bone``.
    radius : {"inscribed", "mean"}
        ``"inscribed"``: distance from the centre to the nearest section segment;
        ``"mean"``: perimeter of the loop containing the centre over 2 pi.
    min_radius : float, m
        Smaller spheres are dropped.
    clamp : bool or None
        Cap each radius by the exact 3-D distance from the centre to the body surface.
        None means True for ``"inscribed"`` and False for ``"mean"``.

    Returns
    -------
    centres : (s, 3) float64, m
    radii : (s,) float64, m
    bone_of : (s,) int64
        Index into ``bones`` of each sphere.
    """
    if radius not in RADIUS_RULES:
        raise InputError(f"unknown radius rule {radius!r}; use one of {list(RADIUS_RULES)}")
    if isinstance(per_bone, bool) or not isinstance(per_bone, (int, np.integer)) or per_bone < 1:
        raise InputError(f"per_bone must be a positive integer, got {per_bone!r}")
    try:
        min_radius = float(min_radius)
    except (TypeError, ValueError):
        raise InputError(f"min_radius must be a number in m, got {min_radius!r}") from None
    if not (np.isfinite(min_radius) and min_radius >= 0.0):
        raise InputError(f"min_radius must be a finite length >= 0 m, got {min_radius!r}")
    verts = np.ascontiguousarray(body_verts, dtype=np.float64)
    if verts.ndim != 2 or verts.shape[1] != 3 or verts.shape[0] == 0:
        raise InputError(f"body_verts must be a non-empty (n, 3) array, got shape {verts.shape}")
    if not np.isfinite(verts).all():
        raise InputError("body_verts contain NaN or infinite coordinates")
    try:
        seg = np.asarray(bones, dtype=np.float64).reshape(-1, 2, 3)
    except ValueError:
        raise InputError("bones must be a list of (head (3,), tail (3,)) pairs in m") from None
    if len(seg) != len(bones) or not np.isfinite(seg).all():
        raise InputError("bones must be a list of finite (head (3,), tail (3,)) pairs in m")
    lengths = np.linalg.norm(seg[:, 1] - seg[:, 0], axis=1)
    if np.any(lengths <= 0.0):
        raise InputError(f"bone {int(np.argmin(lengths))} has zero length")
    clamp = (radius == "inscribed") if clamp is None else bool(clamp)

    sections = MeshSections(body_tris, verts.shape[0])
    surface = _SurfaceDistance(verts, sections.tris) if clamp else None
    ts = (np.arange(per_bone) + 0.5) / per_bone
    centres, radii, bone_of = [], [], []
    for i, (head, tail) in enumerate(seg):
        rot = rotation_to_y((tail - head) / lengths[i])
        rv = verts @ rot.T
        for t in ts:
            p = head + t * (tail - head)
            q = rot @ p
            r = _section_radius(q[[0, 2]], sections.loops(rv, q[1]), radius)
            if r is None:
                continue
            if surface is not None:
                r = surface.below(p, r)
            if r < min_radius:
                continue
            centres.append(p)
            radii.append(r)
            bone_of.append(i)
    return (np.asarray(centres, dtype=np.float64).reshape(-1, 3), np.asarray(radii, dtype=np.float64),
            np.asarray(bone_of, dtype=np.int64))
