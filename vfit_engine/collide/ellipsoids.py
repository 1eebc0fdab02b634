"""Ellipsoids fitted to body segments, as a cloth collider (the seed's bounding-volume collider).

Fit (:func:`fit_ellipsoids`), per segment with at least ``min_vertices`` vertices:

1. axes: principal axes of the segment's vertices (PCA, eigenvectors of the covariance),
   right-handed, longest first;
2. centre: the mid-range of the vertices' coordinates along those axes (the mean of surface
   vertices drifts toward the densely meshed side, the mid-range does not);
3. semi-axes: the half-ranges ``h`` along the axes (the *PCA-extent* ellipsoid) times the
   smallest common scale ``k`` that puts ``quantile`` of the segment's vertices inside:
   ``k = sqrt(quantile_v(sum_i (y_vi / h_i)^2))``, so a few outlying vertices do not blow
   it up (``k`` may be < 1 when they stretched ``h``).

Nothing is placed by hand: the same call fits a morphed body. Response and overlap handling:
:mod:`vfit_engine.kernels.collide_ellipsoid`.
"""
from __future__ import annotations

import numpy as np

from vfit_engine.errors import InputError
from vfit_engine.kernels.collide_ellipsoid import collide_ellipsoids, ellipsoid_signed_distance

#: Default fraction of a segment's vertices inside its ellipsoid.
QUANTILE = 0.98
#: Segments with fewer vertices get no ellipsoid.
MIN_VERTICES = 20


class EllipsoidCollider:
    """A set of (possibly overlapping) solid ellipsoids with a skin, friction and restitution.

    Parameters
    ----------
    centres : (e, 3) float, m
    rotations : (e, 3, 3) float
        Rows are each ellipsoid's unit axes (orthonormal).
    axes : (e, 3) float, m
        Semi-axes along those rows, > 0.
    parts : list of str, optional
        Segment name of each ellipsoid (default ``"e0"``, ``"e1"``, ...).
    skin : float
        Relative margin: the semi-axes are scaled by ``1 + skin`` for the response (like
        :class:`vfit_engine.collide.spheres.SphereCollider`); :meth:`signed_distance` and
        :meth:`surface_samples` use the true ellipsoids.
    friction, restitution : float
        Cf and Cr in [0, 1] (see the sphere collider).
    closest : bool
        False (default, the seed's): radial projection from the centre; True: the true
        closest surface point (Eberly 2013).
    max_rounds : int
        Re-projection rounds for particles in overlaps before the ray fallback.
    """

    def __init__(self, centres, rotations, axes, parts=None, skin=0.01, friction=0.5, restitution=0.0,
                 closest=False, max_rounds=4):
        centres = np.array(centres, dtype=np.float64, order="C").reshape(-1, 3)
        e = centres.shape[0]
        try:
            rotations = np.array(rotations, dtype=np.float64, order="C").reshape(e, 3, 3)
            axes = np.array(axes, dtype=np.float64, order="C").reshape(e, 3)
        except ValueError:
            raise InputError(f"{e} ellipsoid centres but rotations/axes of another count") from None
        if not all(np.all(np.isfinite(a)) for a in (centres, rotations, axes)) or np.any(axes <= 0):
            raise InputError("ellipsoid centres, rotations and axes must be finite and axes > 0")
        ortho = np.einsum("eij,ekj->eik", rotations, rotations) - np.eye(3)
        if e and np.abs(ortho).max() > 1e-6:
            raise InputError("ellipsoid rotations must be orthonormal (rows = unit axes)")
        for name, value, top in (("skin", skin, 10.0), ("friction", friction, 1.0),
                                 ("restitution", restitution, 1.0)):
            if not (np.isfinite(value) and 0.0 <= value <= top):
                raise InputError(f"ellipsoid {name} out of range: {value}")
        if int(max_rounds) < 0:
            raise InputError(f"ellipsoid max_rounds must be >= 0: {max_rounds}")
        parts = [f"e{i}" for i in range(e)] if parts is None else [str(p) for p in parts]
        if len(parts) != e:
            raise InputError(f"{e} ellipsoids but {len(parts)} part names")
        self.centres = centres
        self.rotations = rotations
        self.axes = axes
        self.parts = parts
        self.skin = float(skin)
        self.friction = float(friction)
        self.restitution = float(restitution)
        self.closest = bool(closest)
        self.max_rounds = int(max_rounds)

    @property
    def count(self):
        """Number of ellipsoids."""
        return int(self.axes.shape[0])

    def ellipsoid_arrays(self):
        """Arrays for a kernel: centres (e, 3) m, rotations (e, 3, 3), effective semi-axes
        ``axes * (1 + skin)`` (e, 3) m, friction (e,), restitution (e,)."""
        e = self.count
        return (self.centres, self.rotations, self.axes * (1.0 + self.skin),
                np.full(e, self.friction), np.full(e, self.restitution))

    def project(self, x, x_prev, inv_mass):
        """Push particles out of the (inflated) ellipsoids in place; returns how many moved.

        ``x``, ``x_prev`` C-contiguous float64 (n, 3) m; ``inv_mass`` (n,) 1/kg, 0 = pinned.
        See :mod:`vfit_engine.kernels.collide_ellipsoid` for the formulas.
        """
        if self.count == 0:
            return 0

        return collide_ellipsoids(x, x_prev, inv_mass, *self.ellipsoid_arrays(),
                                  closest=self.closest, max_rounds=self.max_rounds)

    def signed_distance(self, points):
        """Exact distance of each point to the nearest true ellipsoid surface (no skin), m;
        negative inside (the minimum over the parts). ``points`` (n, 3) -> (n,) float64."""
        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        if self.count == 0:
            return np.full(points.shape[0], np.inf)

        return ellipsoid_signed_distance(points, self.centres, self.rotations, self.axes)

    def level(self, points):
        """Level ``sum_i (y_i / a_i)^2`` of each point in each true ellipsoid: (n, e); < 1 inside."""
        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        y = np.einsum("eij,nej->nei", self.rotations, points[:, None, :] - self.centres[None])
        return ((y / self.axes[None]) ** 2).sum(axis=2)

    def surface_samples(self, count_per_part=200, seed=0, exposed=False):
        """Seeded points spread uniformly by area on each true ellipsoid surface (no skin).

        Parameters
        ----------
        count_per_part : int
        seed : int
        exposed : bool
            True: drop the points lying inside another ellipsoid (buried in the union).

        Returns
        -------
        points : (k, 3) float64, m
            ``k = count_per_part * count`` unless ``exposed``.
        part_index : (k,) int64
            Index into :attr:`parts` of the ellipsoid each point lies on.
        """
        count_per_part = int(count_per_part)
        if count_per_part < 1:
            raise InputError(f"count_per_part must be >= 1: {count_per_part}")
        rng = np.random.default_rng(seed)
        pts, idx = [], []
        for e in range(self.count):
            a = self.axes[e]
            got = np.empty((0, 3))
            while got.shape[0] < count_per_part:
                u = rng.normal(size=(4 * count_per_part, 3))
                u /= np.linalg.norm(u, axis=1, keepdims=True)
                # the map u -> a * u stretches area by |a0 a1 a2| |u / a|: accept in proportion
                w = np.linalg.norm(u / a, axis=1) * a.min()
                got = np.vstack([got, u[rng.random(u.shape[0]) < w]])
            y = got[:count_per_part] * a
            pts.append(self.centres[e] + y @ self.rotations[e])
            idx.append(np.full(count_per_part, e, dtype=np.int64))
        if not pts:
            return np.empty((0, 3)), np.empty(0, dtype=np.int64)
        points, part_index = np.vstack(pts), np.concatenate(idx)
        if exposed:
            lev = self.level(points)
            lev[np.arange(points.shape[0]), part_index] = np.inf
            keep = lev.min(axis=1) >= 1.0
            points, part_index = points[keep], part_index[keep]
        return np.ascontiguousarray(points), part_index


def fit_ellipsoids(body_verts, labels, names, quantile=QUANTILE, min_vertices=MIN_VERTICES, **options):
    """One ellipsoid per body segment, bounding ``quantile`` of its vertices (module docstring).

    Parameters
    ----------
    body_verts : (v, 3) float, m
        Body vertices (the 13,380 visible-body vertices of hm08), any shape or pose.
    labels : (v,) int
        Segment index of each vertex into ``names``; negative = unlabelled (ignored).
    names : list of str
        Segment names.
    quantile : float
        Fraction in (0, 1] of each segment's vertices the ellipsoid must contain.
    min_vertices : int
        Segments with fewer vertices are skipped.
    **options
        Passed to :class:`EllipsoidCollider` (skin, friction, restitution, closest, max_rounds).

    Returns
    -------
    EllipsoidCollider
        ``parts`` holds the names of the fitted segments, in ``names`` order.
    """
    verts = np.asarray(body_verts, dtype=np.float64)
    labels = np.asarray(labels).ravel()
    if verts.ndim != 2 or verts.shape[1] != 3 or not np.all(np.isfinite(verts)):
        raise InputError(f"body vertices must be a finite (v, 3) array, got shape {verts.shape}")
    if labels.shape[0] != verts.shape[0] or not np.issubdtype(labels.dtype, np.integer):
        raise InputError(f"need one integer label per body vertex: {labels.shape[0]} labels, "
                         f"{verts.shape[0]} vertices")
    if not (0.0 < quantile <= 1.0):
        raise InputError(f"ellipsoid quantile must be in (0, 1]: {quantile}")
    if labels.size and labels.max() >= len(names):
        raise InputError(f"label {labels.max()} but only {len(names)} segment names")
    centres, rotations, axes, parts = [], [], [], []
    for k, name in enumerate(names):
        pts = verts[labels == k]
        if pts.shape[0] < max(int(min_vertices), 4):
            continue
        c, rot, a = _fit_one(pts, quantile)
        centres.append(c)
        rotations.append(rot)
        axes.append(a)
        parts.append(str(name))
    if not parts:
        raise InputError(f"no segment has {min_vertices} or more vertices")
    return EllipsoidCollider(np.array(centres), np.array(rotations), np.array(axes), parts=parts, **options)


def _fit_one(pts, quantile):
    """Centre (3,), rotation (3, 3) rows = axes, semi-axes (3,) of one segment."""
    mean = pts.mean(axis=0)
    _, vecs = np.linalg.eigh(np.cov((pts - mean).T))
    rot = vecs[:, ::-1].T.copy()  # longest axis first
    if np.linalg.det(rot) < 0:
        rot[2] *= -1.0
    y = (pts - mean) @ rot.T
    lo, hi = y.min(axis=0), y.max(axis=0)
    mid = 0.5 * (lo + hi)
    # a flat segment would give a zero half-range: keep a floor of 1 mm
    half = np.maximum(0.5 * (hi - lo), 1e-3)
    y -= mid
    lev = ((y / half) ** 2).sum(axis=1)
    scale = np.sqrt(np.quantile(lev, quantile, method="higher"))
    scale = max(scale, 1e-6)
    return mean + mid @ rot, rot, half * scale
