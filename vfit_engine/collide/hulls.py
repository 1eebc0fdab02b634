"""Convex hulls per body segment plus joint spheres, as an auto-fitted cloth collider.

Fit (:func:`fit_hulls`), for any body given as plain arrays (no hand placement):

1. Hulls. For every segment with at least ``min_vertices`` vertices, the convex hull of its
   vertices (QuickHull, Barber et al. 1996, through :class:`scipy.spatial.ConvexHull`) is
   simplified: when it has more than ``max_faces`` facets, a subset of its vertices is chosen by
   farthest-point sampling (``max_faces // 2 + 2`` points: a triangulated convex polytope on
   ``k`` points has at most ``2k - 4`` facets) and only the facet planes of the subset's hull are
   kept. Each plane ``n . x <= b`` is then pushed out to ``b = max over the segment's vertices of
   n . x``, plus ``inflate``: so every segment vertex lies inside its hull by at least
   ``inflate`` whatever the simplification did.
2. Joint spheres. Two segments are adjacent when a body edge joins them (``body_tris``); the
   joint's boundary vertices are the vertices of either segment with a neighbour in the other.
   The sphere's centre is their mean, its radius their mean distance to that centre
   (``joint_radius="min"``: their least distance).

The collider (:class:`HullCollider`) stores every hull as half-spaces (``normals`` (H, 3),
``offsets`` (H,), CSR ``hull_start`` (h + 1,)) -- planes that touch no face of the polytope are
dropped -- and, for exact distances outside, the triangles of the polytope's boundary: the
convex hull of its vertices, found by half-space intersection (:class:`scipy.spatial.
HalfspaceIntersection`) around the polytope's Chebyshev centre. Shapes are tested in the world
frame: with planes, a per-hull local frame would change no test, only add a transform.

Response: see :mod:`vfit_engine.kernels.collide_hull` (least-penetration face for hulls,
radial push for spheres, the nearest candidate carried on outside every other shape, Cf/Cr
split).
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import linprog
from scipy.spatial import ConvexHull, HalfspaceIntersection, QhullError

from vfit_engine.errors import InputError
from vfit_engine.kernels.collide_hull import collide_hulls, hull_signed_distance

#: Segments with fewer vertices get no hull (and no joint sphere).
MIN_VERTICES = 20
#: Normals closer than this (1 - cos) are one plane.
_SAME_NORMAL = 1e-10
#: A plane is a facet of the polytope when at least 3 polytope vertices lie within this of it, m.
_ON_PLANE = 1e-9


def _polytope(normals, offsets):
    """Vertices and boundary triangles of ``{x : normals @ x <= offsets}`` and the facet mask.

    Returns ``verts (V, 3)``, ``tris (T, 3) int64`` (outward, counter-clockwise) and
    ``facet (H,) bool`` (planes touching the polytope in a face). Raises InputError when the
    set is empty, flat or unbounded.
    """
    # Chebyshev centre: max r with n . c + r |n| <= b (unit normals)
    h = normals.shape[0]
    res = linprog(np.r_[0.0, 0.0, 0.0, -1.0], A_ub=np.c_[normals, np.ones(h)], b_ub=offsets,
                  bounds=[(None, None)] * 3 + [(0.0, None)], method="highs")
    if res.status != 0 or res.x[3] <= 1e-9:
        raise InputError("hull planes do not bound a solid (empty, flat or unbounded)")
    try:
        with np.errstate(divide="ignore", invalid="ignore"):  # unbounded sets: caught below
            hs = HalfspaceIntersection(np.c_[normals, -offsets], res.x[:3])
            pts = hs.intersections
        if not np.all(np.isfinite(pts)):
            raise InputError("hull planes do not bound a finite solid")
        hull = ConvexHull(pts)
    except QhullError as exc:
        raise InputError(f"hull planes do not bound a solid: {str(exc).splitlines()[0]}") from None
    verts = pts[hull.vertices]
    remap = np.full(pts.shape[0], -1, dtype=np.int64)
    remap[hull.vertices] = np.arange(hull.vertices.shape[0])
    tris = remap[hull.simplices]
    a, b, c = verts[tris[:, 0]], verts[tris[:, 1]], verts[tris[:, 2]]
    flip = np.einsum("ij,ij->i", np.cross(b - a, c - a), hull.equations[:, :3]) < 0
    tris[flip] = tris[flip][:, ::-1]
    on = np.abs(verts @ normals.T - offsets[None, :]) <= _ON_PLANE * max(1.0, float(np.abs(offsets).max()))
    return verts, np.ascontiguousarray(tris, dtype=np.int64), on.sum(axis=0) >= 3


def _farthest_points(p, k):
    """Indices of ``k`` points of ``p`` by farthest-point sampling, from the farthest from the mean."""
    first = int(np.argmax(np.linalg.norm(p - p.mean(axis=0), axis=1)))
    chosen = [first]
    dist = np.linalg.norm(p - p[first], axis=1)
    for _ in range(1, min(k, p.shape[0])):
        j = int(np.argmax(dist))
        chosen.append(j)
        dist = np.minimum(dist, np.linalg.norm(p - p[j], axis=1))
    return np.array(chosen, dtype=np.int64)


def hull_planes(points, max_faces=64, inflate=0.003):
    """Outward planes of a simplified convex hull containing ``points`` (module docstring, step 1).

    Parameters
    ----------
    points : (m, 3) float, m
    max_faces : int
        Most planes kept (>= 4).
    inflate : float, m
        Every point lies at least this far inside every plane.

    Returns
    -------
    normals : (H, 3) float64
        Unit outward normals, H <= max_faces.
    offsets : (H,) float64, m
        ``b = max_i n . p_i + inflate``.
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    hull = ConvexHull(p)
    eq = hull.equations
    if eq.shape[0] > max_faces:
        hv = p[hull.vertices]
        eq = ConvexHull(hv[_farthest_points(hv, max_faces // 2 + 2)]).equations
    normals = eq[:, :3] / np.linalg.norm(eq[:, :3], axis=1, keepdims=True)
    keep = []
    for j in range(normals.shape[0]):
        if all(1.0 - normals[j] @ normals[i] > _SAME_NORMAL for i in keep):
            keep.append(j)
    normals = np.ascontiguousarray(normals[keep])
    offsets = (p @ normals.T).max(axis=0) + inflate
    return normals, offsets


def _joints(body_verts, labels, tris, has_hull, radius="mean"):
    """Joint spheres between adjacent segments that both have hulls: centres, radii, (a, b) pairs."""
    e = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
    la, lb = labels[e[:, 0]], labels[e[:, 1]]
    cut = (la != lb) & has_hull[la] & has_hull[lb]
    e, la, lb = e[cut], la[cut], lb[cut]
    lo, hi = np.minimum(la, lb), np.maximum(la, lb)
    centres, radii, pairs = [], [], []
    for a, b in sorted(set(zip(lo.tolist(), hi.tolist()))):
        sel = (lo == a) & (hi == b)
        idx = np.unique(e[sel].ravel())
        if idx.shape[0] < 3:
            continue
        pts = body_verts[idx]
        c = pts.mean(axis=0)
        dist = np.linalg.norm(pts - c, axis=1)
        r = float(dist.mean() if radius == "mean" else dist.min())
        if r <= 0.0:
            continue
        centres.append(c)
        radii.append(r)
        pairs.append((a, b))
    return np.array(centres, dtype=np.float64).reshape(-1, 3), np.array(radii, dtype=np.float64), pairs


def fit_hulls(body_verts, labels, names, body_tris=None, max_faces=64, inflate=0.003,
              min_vertices=MIN_VERTICES, joint_spheres=True, joint_radius="mean", skin=0.002, friction=0.3,
              restitution=0.0):
    """Fit one convex hull per segment and a sphere per joint (module docstring).

    Parameters
    ----------
    body_verts : (N, 3) float, m
        Body vertices (the first 13,380 of a BodyModel mesh, or any mesh).
    labels : (N,) int
        Segment index of each vertex, into ``names``.
    names : list of str
        Segment names.
    body_tris : (T, 3) int or None
        Body triangles, for joint adjacency; no joint spheres without them.
    max_faces : int
        Most planes per hull (>= 4).
    inflate : float, m
        Outward margin of every hull plane beyond the farthest segment vertex.
    min_vertices : int
        Segments with fewer vertices are skipped.
    joint_spheres : bool
    joint_radius : {"mean", "min"}
        Sphere radius: the mean distance of the boundary vertices to the joint centre (round
        joints: knees, elbows, wrists) or the least one, so the sphere does not bulge out of a
        flat cross-section (the waist, where "mean" overshoots the skin by up to ~5 cm).
    skin, friction, restitution
        Passed to :class:`HullCollider`.

    Returns
    -------
    HullCollider
    """
    v = np.asarray(body_verts, dtype=np.float64)
    lab = np.asarray(labels)
    names = [str(n) for n in names]
    if v.ndim != 2 or v.shape[1] != 3 or not np.all(np.isfinite(v)):
        raise InputError("body_verts must be a finite (N, 3) array")
    if lab.shape != (v.shape[0],) or not np.issubdtype(lab.dtype, np.integer):
        raise InputError(f"labels must be ({v.shape[0]},) integers, got {lab.shape} {lab.dtype}")
    if lab.size and (lab.min() < 0 or lab.max() >= len(names)):
        raise InputError(f"labels must index names (0..{len(names) - 1})")
    if int(max_faces) < 4:
        raise InputError(f"max_faces must be >= 4, got {max_faces}")
    if joint_radius not in ("mean", "min"):
        raise InputError(f"joint_radius must be 'mean' or 'min', got {joint_radius!r}")
    if not (np.isfinite(inflate) and inflate >= 0.0):
        raise InputError(f"inflate must be >= 0 m, got {inflate}")
    lab = lab.astype(np.int64)
    normals, offsets, starts, parts = [], [], [0], []
    has_hull = np.zeros(len(names), dtype=bool)
    for k, name in enumerate(names):
        pts = v[lab == k]
        if pts.shape[0] < max(int(min_vertices), 4):
            continue
        try:
            n, b = hull_planes(pts, int(max_faces), float(inflate))
        except QhullError:
            continue  # a flat or degenerate segment: no solid to hull
        normals.append(n)
        offsets.append(b)
        starts.append(starts[-1] + n.shape[0])
        parts.append(name)
        has_hull[k] = True
    if not parts:
        raise InputError(f"no segment has {min_vertices} or more vertices to hull")
    centres, radii = np.zeros((0, 3)), np.zeros(0)
    if joint_spheres and body_tris is not None:
        tris = np.asarray(body_tris, dtype=np.int64)
        if tris.ndim != 2 or tris.shape[1] != 3 or (tris.size and (tris.min() < 0 or tris.max() >= v.shape[0])):
            raise InputError("body_tris must be (T, 3) indices into body_verts")
        centres, radii, pairs = _joints(v, lab, tris, has_hull, joint_radius)
        parts += [f"{names[a]}|{names[b]}" for a, b in pairs]
    return HullCollider(np.concatenate(normals), np.concatenate(offsets), np.array(starts, dtype=np.int64),
                        centres, radii, parts=parts, skin=skin, friction=friction, restitution=restitution)


class HullCollider:
    """Convex polytopes (half-space sets) and spheres with a skin, friction and restitution.

    Parameters
    ----------
    normals : (H, 3) float, unit outward plane normals (normalised here)
    offsets : (H,) float, m
        Hull ``k`` is ``{x : n_j . x <= b_j, j in hull_start[k]:hull_start[k + 1]}``.
    hull_start : (h + 1,) int
    sphere_centres : (s, 3) float, m
    sphere_radii : (s,) float, m
    parts : list of str or None
        Name of each hull then each sphere.
    skin : float, m
        Absolute margin used by :meth:`project` only: planes move out by ``skin``, sphere
        radii grow by ``skin``; it keeps cloth edges between surface particles off the hull
        corners and leaves room for the cloth's thickness. :meth:`signed_distance` and :meth:`surface_samples` ignore it.
    friction, restitution : float
        Cf and Cr in [0, 1] (see :mod:`vfit_engine.kernels.collide_hull`).

    Attributes
    ----------
    normals, offsets, hull_start
        Facet planes only (planes touching no face are dropped).
    tri_verts : (V, 3) float64, m ; tris : (T, 3) int64 ; tri_start : (h + 1,) int64
        Boundary triangles of each hull (outward), for distances outside.
    sphere_centres : (s, 3) float64, m ; sphere_radii : (s,) float64, m
    parts : list of str
    """

    def __init__(self, normals, offsets, hull_start, sphere_centres=None, sphere_radii=None, parts=None,
                 skin=0.002, friction=0.3, restitution=0.0):
        normals = np.array(normals, dtype=np.float64).reshape(-1, 3)
        offsets = np.array(offsets, dtype=np.float64).ravel()
        starts = np.array(hull_start, dtype=np.int64).ravel()
        if offsets.shape[0] != normals.shape[0]:
            raise InputError(f"{normals.shape[0]} hull normals but {offsets.shape[0]} offsets")
        if starts.shape[0] < 1 or starts[0] != 0 or starts[-1] != normals.shape[0] or np.any(np.diff(starts) < 4):
            raise InputError("hull_start must run from 0 to the plane count with >= 4 planes per hull")
        norm = np.linalg.norm(normals, axis=1)
        if not (np.all(np.isfinite(normals)) and np.all(np.isfinite(offsets))) or np.any(norm <= 0):
            raise InputError("hull planes must be finite with non-zero normals")
        normals, offsets = normals / norm[:, None], offsets / norm
        centres = np.zeros((0, 3)) if sphere_centres is None else np.array(sphere_centres, dtype=np.float64)
        radii = np.zeros(0) if sphere_radii is None else np.array(sphere_radii, dtype=np.float64).ravel()
        centres = centres.reshape(-1, 3)
        if radii.shape[0] != centres.shape[0]:
            raise InputError(f"{centres.shape[0]} sphere centres but {radii.shape[0]} radii")
        if not (np.all(np.isfinite(centres)) and np.all(np.isfinite(radii))) or np.any(radii <= 0):
            raise InputError("sphere centres must be finite and radii finite and > 0")
        for name, value, hi in (("skin", skin, 0.1), ("friction", friction, 1.0), ("restitution", restitution, 1.0)):
            if not (np.isfinite(value) and 0.0 <= value <= hi):
                raise InputError(f"hull collider {name} out of range: {value}")
        h = starts.shape[0] - 1
        if parts is None:
            parts = [f"hull{k}" for k in range(h)] + [f"sphere{k}" for k in range(radii.shape[0])]
        if len(parts) != h + radii.shape[0]:
            raise InputError(f"{len(parts)} part names for {h} hulls and {radii.shape[0]} spheres")
        self._skin = float(skin)
        self.friction = float(friction)
        self.restitution = float(restitution)
        self.parts = [str(p) for p in parts]
        self.sphere_centres = np.ascontiguousarray(centres)
        self.sphere_radii = np.ascontiguousarray(radii)
        new_n, new_b, new_s, tv, tt, ts = [], [], [0], [], [], [0]
        centres_h, reach = np.zeros((h, 3)), np.zeros(h)
        base = 0
        for k in range(h):
            n, b = normals[starts[k]:starts[k + 1]], offsets[starts[k]:starts[k + 1]]
            verts, tris, facet = _polytope(n, b)
            n, b = n[facet], b[facet]
            new_n.append(n)
            new_b.append(b)
            new_s.append(new_s[-1] + n.shape[0])
            tv.append(verts)
            tt.append(tris + base)
            ts.append(ts[-1] + tris.shape[0])
            base += verts.shape[0]
            # bounding sphere of the skinned hull: its vertices move by more than skin at sharp corners
            skinned = _polytope(n, b + self._skin)[0] if self._skin > 0 else verts
            centres_h[k] = skinned.mean(axis=0)
            reach[k] = np.linalg.norm(skinned - centres_h[k], axis=1).max() * (1.0 + 1e-9) + 1e-12
        self.normals = np.ascontiguousarray(np.concatenate(new_n))
        self.offsets = np.ascontiguousarray(np.concatenate(new_b))
        self.hull_start = np.array(new_s, dtype=np.int64)
        self.tri_verts = np.ascontiguousarray(np.concatenate(tv))
        self.tris = np.ascontiguousarray(np.concatenate(tt), dtype=np.int64)
        self.tri_start = np.array(ts, dtype=np.int64)
        self._hull_centres = centres_h
        self._hull_reach = reach

    @property
    def skin(self):
        """Projection margin, m (read-only: the hulls' bounding spheres are built for it)."""
        return self._skin

    @property
    def hull_count(self):
        return int(self.hull_start.shape[0] - 1)

    @property
    def sphere_count(self):
        return int(self.sphere_radii.shape[0])

    @property
    def count(self):
        """Number of parts: hulls then spheres."""
        return self.hull_count + self.sphere_count

    def project(self, x, x_prev, inv_mass):
        """Push free particles out of every hull and sphere (skin included) in place.

        ``x``, ``x_prev`` C-contiguous float64 (n, 3), m; ``inv_mass`` (n,) 1/kg, 0 = pinned.
        See :mod:`vfit_engine.kernels.collide_hull` for the rule.
        """
        collide_hulls(x, x_prev, inv_mass, self.normals, self.offsets + self.skin, self.hull_start,
                      self._hull_centres, self._hull_reach, self.sphere_centres, self.sphere_radii + self.skin,
                      self.friction, self.restitution)

    def signed_distance(self, points):
        """Exact signed distance to the union of the parts (no skin), m; negative inside.

        Inside a hull it is ``max_j (n_j . x - b_j)``, outside the distance to its triangles;
        the minimum over parts is exact outside the union and inside it is the depth in the
        part the point is deepest in. ``points`` (n, 3) -> (n,) float64.
        """
        return hull_signed_distance(points, self.normals, self.offsets, self.hull_start, self.tri_verts, self.tris,
                                    self.tri_start, self.sphere_centres, self.sphere_radii)

    def surface_samples(self, count_per_part=200, seed=0, exposed=True):
        """Seeded random points on the parts' surfaces (no skin).

        Hulls are sampled uniformly by area over their triangles, spheres uniformly.

        Parameters
        ----------
        count_per_part : int
        seed : int
        exposed : bool
            Drop samples lying inside another part (they are not on the collider's surface).

        Returns
        -------
        points : (k, 3) float64, m
        part_index : (k,) int64
            Index into :attr:`parts` of each sample.
        """
        rng = np.random.default_rng(seed)
        m = int(count_per_part)
        pts, idx = [], []
        for k in range(self.hull_count):
            t = self.tris[self.tri_start[k]:self.tri_start[k + 1]]
            a, b, c = self.tri_verts[t[:, 0]], self.tri_verts[t[:, 1]], self.tri_verts[t[:, 2]]
            area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
            pick = rng.choice(t.shape[0], size=m, p=area / area.sum())
            u, w = rng.random(m), rng.random(m)
            over = u + w > 1.0
            u[over], w[over] = 1.0 - u[over], 1.0 - w[over]
            pts.append(a[pick] + u[:, None] * (b[pick] - a[pick]) + w[:, None] * (c[pick] - a[pick]))
            idx.append(np.full(m, k, dtype=np.int64))
        for s in range(self.sphere_count):
            d = rng.normal(size=(m, 3))
            d /= np.linalg.norm(d, axis=1, keepdims=True)
            pts.append(self.sphere_centres[s] + self.sphere_radii[s] * d)
            idx.append(np.full(m, self.hull_count + s, dtype=np.int64))
        points = np.concatenate(pts) if pts else np.zeros((0, 3))
        part = np.concatenate(idx) if idx else np.zeros(0, dtype=np.int64)
        if exposed and points.shape[0]:
            keep = np.ones(points.shape[0], dtype=bool)
            for k in range(self.count):
                others = part != k
                keep[others] &= self._part_depth(k, points[others]) >= -1e-9
            points, part = points[keep], part[keep]
        return np.ascontiguousarray(points), part

    def _part_depth(self, k, points):
        """Signed depth of points in part ``k`` (exact inside, a lower bound of distance outside)."""
        if k < self.hull_count:
            s, e = self.hull_start[k], self.hull_start[k + 1]
            return (points @ self.normals[s:e].T - self.offsets[s:e]).max(axis=1)
        s = k - self.hull_count
        return np.linalg.norm(points - self.sphere_centres[s], axis=1) - self.sphere_radii[s]
