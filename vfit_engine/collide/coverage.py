"""How well an approximate collider covers the body it was fitted to, part by part.

Two ways a collider made of simple shapes (spheres, ellipsoids, convex hulls) misses the body:

* **gaps**: body vertices outside every shape -- cloth can sink into the body there (measured
  as the fraction of each part's vertices with collider signed distance > 0, and the largest
  such distance);
* **overshoot**: collider surface standing off the skin -- cloth floats there (measured on
  seeded samples of the exposed collider surface, i.e. not buried in another shape, as their
  signed distance to the exact body mesh, > 0 outside the body).

The exact body mesh collider has neither by construction (its skin offset aside).
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree


def surface_samples(collider, count_per_part=200, seed=0):
    """Exposed surface samples of a fitted collider.

    Parameters
    ----------
    collider : SphereCollider, EllipsoidCollider or HullCollider
    count_per_part : int
    seed : int

    Returns
    -------
    points : (k, 3) float64, m
    """
    if hasattr(collider, "surface_samples"):
        pts, _ = collider.surface_samples(count_per_part=count_per_part, seed=seed, exposed=True)
        return np.asarray(pts, dtype=np.float64)
    # spheres: uniform directions on each sphere, keeping points not inside another sphere
    rng = np.random.default_rng(seed)
    u = rng.normal(size=(collider.count, count_per_part, 3))
    u /= np.linalg.norm(u, axis=2, keepdims=True)
    pts = (collider.centres[:, None, :] + collider.radii[:, None, None] * u).reshape(-1, 3)
    return pts[collider.signed_distance(pts) >= -1e-9]


def coverage(collider, body_verts, labels, names, body_collider, count_per_part=200, seed=0):
    """Gaps and overshoot of ``collider`` against the body, per body part and in total.

    Parameters
    ----------
    collider : SphereCollider, EllipsoidCollider or HullCollider
        Anything with ``signed_distance(points) -> (n,) m`` (negative inside).
    body_verts : (N, 3) float64, m
        The body's vertices (``labels`` gives their parts).
    labels : (N,) int64;  names : list of str
        Part of each vertex (:func:`vfit_engine.body.segment.segment`).
    body_collider : MeshCollider
        The exact body.
    count_per_part : int;  seed : int
        Surface samples per collider part.

    Returns
    -------
    dict
        ``parts``: {name: {vertices, outside_fraction, max_gap_mm, overshoot_p95_mm,
        overshoot_max_mm, samples}}, and ``total`` with the same keys over the whole body.
        Overshoot samples are assigned to the part of their nearest body vertex.
    """
    body = np.ascontiguousarray(body_verts, dtype=np.float64)
    labels = np.asarray(labels, dtype=np.int64)[:body.shape[0]]
    body = body[:labels.size]
    gap = collider.signed_distance(body)
    pts = surface_samples(collider, count_per_part, seed)
    off = body_collider.query(pts, max_out=0.25, max_in=0.25)[0] if len(pts) else np.zeros(0)
    off = np.where(np.isfinite(off), off, np.sign(off) * 0.25)
    near = labels[cKDTree(body).query(pts)[1]] if len(pts) else np.zeros(0, np.int64)

    def stats(vmask, smask):
        g = gap[vmask]
        o = np.maximum(off[smask], 0.0)
        return dict(vertices=int(vmask.sum()), outside_fraction=float(np.mean(g > 0)) if g.size else 0.0,
                    max_gap_mm=1000.0 * float(max(g.max(), 0.0)) if g.size else 0.0,
                    overshoot_p95_mm=1000.0 * float(np.percentile(o, 95)) if o.size else 0.0,
                    overshoot_max_mm=1000.0 * float(o.max()) if o.size else 0.0, samples=int(smask.sum()))

    parts = {name: stats(labels == k, near == k) for k, name in enumerate(names) if np.any(labels == k)}
    return dict(parts=parts, total=stats(np.ones(labels.size, bool), np.ones(len(pts), bool)))
