"""A drape simulated on a finer mesh than the garment's own (``DrapeSettings.refine``), mapped back.

A fold needs a few polygons across it: on a garment modelled coarsely (the demo skirt's 64 columns, 37 mm
apart at the hem) silk cannot fall into its many narrow folds, and silk and denim drape alike (4 mm apart on
average). Each level splits every k-sided polygon into k quads (corner, edge midpoints, centroid): the
garment's own vertices keep their numbers ``0 .. n - 1`` and the new ones follow, so the garment's vertices
are read back from the fine cloth as they are, and everything measured and written keeps the garment's own
vertices (its file's order, UVs, edges for the yarn strain).

The fine cloth is the coarse one linearly interpolated (``fine = W @ coarse`` for the rest shape, the start
and the pin targets): the same surface, so the same rest lengths along every edge, and the material's
measured bending, stretch and weight are mapped per unit area and length (:mod:`vfit_engine.sim.materials`),
the same at any spacing. A new vertex is pinned where all its parents are (a waistband stays a band), and
stretches as an opening's cloth may where all its parents may.
"""
from __future__ import annotations

import dataclasses

import numpy as np
from scipy.sparse import csr_matrix, identity

from vfit_engine.drape.setup import Pins
from vfit_engine.io.meshdata import MeshData


def subdivide(mesh):
    """One level of linear subdivision of a polygon mesh.

    Parameters
    ----------
    mesh : MeshData

    Returns
    -------
    fine : MeshData
        Every k-sided polygon as k quads (corner, next edge's midpoint, centroid, previous edge's midpoint),
        in the polygon's winding; vertices: the mesh's own first, then the edge midpoints, then the centroids.
        No UVs.
    weights : scipy.sparse.csr_matrix, (n_fine, n)
        ``fine.verts = weights @ mesh.verts``.
    """
    n = mesh.n_verts
    fo, fv = np.asarray(mesh.face_offsets, np.int64), np.asarray(mesh.face_verts, np.int64)
    sizes = np.diff(fo)
    face = np.repeat(np.arange(len(sizes)), sizes)
    nxt = np.arange(len(fv)) + 1
    nxt[fo[1:] - 1] = fo[:-1]  # each corner's next corner in its face
    a, b = fv, fv[nxt]
    key = np.minimum(a, b) * n + np.maximum(a, b)
    edges, corner_edge = np.unique(key, return_inverse=True)
    ne, nf = len(edges), len(sizes)
    mid = n + corner_edge  # the midpoint vertex of each corner's next edge
    centre = n + ne + face
    prev = np.empty_like(nxt)
    prev[nxt] = np.arange(len(fv))
    quads = np.stack([fv, mid, centre, mid[prev]], axis=1).reshape(-1)
    rows = np.concatenate([np.arange(n), np.repeat(n + np.arange(ne), 2), n + ne + face])
    cols = np.concatenate([np.arange(n), np.stack([edges // n, edges % n], axis=1).reshape(-1), fv])
    vals = np.concatenate([np.ones(n), np.full(2 * ne, 0.5), 1.0 / sizes[face]])
    weights = csr_matrix((vals, (rows, cols)), shape=(n + ne + nf, n))
    fine = MeshData(np.ascontiguousarray(weights @ mesh.verts), np.arange(0, 4 * len(fv) + 1, 4, dtype=np.int64),
                    quads.astype(np.int64))
    return fine, weights


def refine_setup(setup, levels):
    """The :class:`~vfit_engine.drape.setup.DrapeSetup` of the cloth subdivided ``levels`` times; with the
    (n_fine, n) map of the garment's vertices to the fine ones (module docstring)."""
    mesh, weights = setup.garment.mesh, identity(setup.garment.mesh.n_verts, format="csr")
    for _ in range(int(levels)):
        mesh, w = subdivide(mesh)
        weights = (w @ weights).tocsr()
    pinned = np.zeros(setup.garment.mesh.n_verts, bool)
    pinned[setup.pins.indices] = True
    idx = np.flatnonzero(_all_parents(weights, pinned))
    targets = np.zeros((setup.garment.mesh.n_verts, 3))
    targets[setup.pins.indices] = setup.pins.targets
    zones = []
    for zone, strain in setup.zones:
        inside = np.zeros(setup.garment.mesh.n_verts, bool)
        inside[zone] = True
        zones.append((np.flatnonzero(_all_parents(weights, inside)), strain))
    pieces = setup.garment.pieces
    if pieces is not None:  # a fine vertex's parents are one polygon's corners: one piece, their mean label
        pieces = np.rint(weights @ np.asarray(pieces, dtype=np.float64)).astype(np.int64)
    garment = dataclasses.replace(setup.garment, mesh=mesh, pieces=pieces)
    fine = dataclasses.replace(setup, garment=garment, rest=np.ascontiguousarray(weights @ setup.rest),
                               start=np.ascontiguousarray(weights @ setup.start),
                               pins=Pins(idx, np.ascontiguousarray((weights @ targets)[idx]), setup.pins.info),
                               zones=zones)
    return fine, weights


def _all_parents(weights, flag):
    """(n_fine,) bool: the fine vertices whose every parent (nonzero weight) has ``flag``."""
    parents = weights.copy()
    parents.data[:] = 1.0
    return np.asarray(parents @ (~flag).astype(np.float64)) == 0.0
