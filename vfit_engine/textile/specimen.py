"""Flat specimens for the fabric tests, meshed at a given spacing, lying in the horizontal (x-z) plane.

Shapes::

    annulus(inner, outer, edge)   -> pos (n, 3) m, face_verts (k,), face_offsets (m+1,), ring (n,)   quads
    disc(radius, edge, seed)      -> pos (n, 3) m, face_verts (k,), face_offsets (m+1,)             triangles

The cantilever's strip is a grid of quads (:func:`vfit_engine.sim.springs.grid_polygons`); the disc of
near-equilateral triangles measures the bending model without a quad grid's directions.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import Delaunay


def disc(radius, edge, seed=0):
    """A disc of near-equilateral triangles of side ``edge``: a hexagonal lattice, each point moved by up to
    a tenth of the spacing (seeded: no direction of the lattice stands out), and a ring of points on the
    rim; Delaunay-triangulated. Vertex 0 is the centre."""
    rng = np.random.default_rng(seed)
    rows = int(np.ceil(radius / (edge * np.sqrt(0.75)))) + 1
    j, i = np.meshgrid(np.arange(-rows, rows + 1), np.arange(-rows - 1, rows + 2), indexing="ij")
    x = (i + 0.5 * (j % 2)) * edge
    z = j * edge * np.sqrt(0.75)
    pts = np.stack([x.ravel(), z.ravel()], axis=1)
    r = np.hypot(pts[:, 0], pts[:, 1])
    centre = np.argmin(r)
    pts = np.r_[pts[centre:centre + 1], pts[(r < radius - 0.5 * edge) & (np.arange(r.size) != centre)]]
    pts[1:] += rng.uniform(-0.1, 0.1, size=(pts.shape[0] - 1, 2)) * edge
    n_rim = max(8, int(np.round(2 * np.pi * radius / edge)))
    a = np.arange(n_rim) * 2 * np.pi / n_rim
    pts = np.r_[pts, radius * np.stack([np.cos(a), np.sin(a)], axis=1)]
    tris = Delaunay(pts).simplices.astype(np.int64)
    pos = np.stack([pts[:, 0], np.zeros(pts.shape[0]), pts[:, 1]], axis=1)
    return pos, tris.ravel(), np.arange(0, tris.size + 1, 3, dtype=np.int64)


def annulus(inner, outer, edge):
    """A ring of quads from radius ``inner - edge`` to ``outer`` (m): rings ``edge`` or just under it apart, the
    same number of quads round every ring (their side ``edge`` at mid radius), as a garment's quads are.
    Returns also the ring index of every vertex (0: the innermost)."""
    n_r = max(2, int(np.ceil((outer - inner) / edge - 1e-9)))
    radii = np.r_[inner - (outer - inner) / n_r, np.linspace(inner, outer, n_r + 1)]
    n_a = max(8, int(np.round(np.pi * (inner + outer) / edge)))
    a = np.arange(n_a) * 2 * np.pi / n_a
    r, aa = np.meshgrid(radii, a, indexing="ij")
    pos = np.stack([(r * np.cos(aa)).ravel(), np.zeros(r.size), (r * np.sin(aa)).ravel()], axis=1)
    ring = np.repeat(np.arange(radii.size), n_a)
    i, j = np.meshgrid(np.arange(radii.size - 1), np.arange(n_a), indexing="ij")
    v00 = (i * n_a + j).ravel()
    v01 = (i * n_a + (j + 1) % n_a).ravel()
    fv = np.stack([v00, v01, v01 + n_a, v00 + n_a], axis=1).ravel().astype(np.int64)
    return pos, fv, np.arange(0, fv.size + 1, 4, dtype=np.int64), ring
