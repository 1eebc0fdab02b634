"""Where the cloth touches the body: its vertices and points spread over its polygons.

A cloth held out of the body at its vertices only still cuts into it between them: a triangle
whose corners rest 2 mm off a convex body sags into it by ``L^2 / (8 R)`` across an edge of length
``L`` on a radius ``R`` (6 mm for a 5 cm edge on a 5 cm thigh), and a bump of the body (a
shin bone, a hip) can poke through a triangle whose corners are all outside. So the collider
holds out a set of *contact points* ``p = sum_k b_k x_k`` embedded in the cloth's triangles as
well (:mod:`vfit_engine.kernels.cloth` pushes such a point out by moving its triangle's vertices).

The points lie on the triangles a viewer draws: each polygon's fan from its first corner (what
OBJ readers, trimesh and the acceptance check use), plus the midpoint of a quad's other diagonal,
so that the other triangulation is held out too. On every edge of the fan (polygon edges and fan
diagonals) the points are ``ceil(L / spacing) - 1`` equally spaced ones; inside a triangle the
interior points of the barycentric lattice of order ``ceil(L_max / spacing)``. Between points
``spacing`` apart the body's sag is at most ``spacing^2 / (8 R)``: 0.6 mm at 15 mm on a radius of
5 cm, which the points' clearance covers.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from vfit_engine.collide.sag import SAG_TOLERANCE, convex_sag
from vfit_engine.io.meshdata import MeshData


@dataclass(frozen=True)
class ContactPointSet:
    """Contact points of a cloth.

    Attributes
    ----------
    verts : (P, 3) int64
        The three cloth vertices each point is a weighted sum of (a cloth vertex ``i`` is
        ``(i, i, i)``).
    bary : (P, 3) float64
        Weights, summing to 1 (a cloth vertex: ``(1, 0, 0)``).
    vertex_count : int
        The first ``vertex_count`` points are the cloth's vertices, in order.
    spacing : float, m
        The largest distance between neighbouring points of the triangles' lattices (0: the vertices only).
    """

    verts: np.ndarray
    bary: np.ndarray
    vertex_count: int
    spacing: float = 0.0

    @property
    def count(self):
        return int(self.verts.shape[0])

    def joined(self, other):
        """This set with ``other``'s points other than its vertices appended (``other``: points over other
        polygons on the same vertex numbering, e.g. the garment's own over a subdivided cloth)."""
        return ContactPointSet(np.concatenate([self.verts, other.verts[other.vertex_count:]]),
                               np.concatenate([self.bary, other.bary[other.vertex_count:]]), self.vertex_count,
                               max(self.spacing, other.spacing))

    def positions(self, pos):
        """(P, 3) float64: the points' positions on cloth positions ``pos`` (n, 3)."""
        return np.einsum("pk,pkd->pd", self.bary, np.asarray(pos, dtype=np.float64)[self.verts])


def contact_points(face_verts, face_offsets, rest_pos, spacing=0.015, surface=True):
    """The vertices and, with ``surface``, points over the fan triangles (module docstring).

    Parameters
    ----------
    face_verts : (k,) int64;  face_offsets : (m + 1,) int64
        Flat polygons.
    rest_pos : (n, 3) float64, m
        Positions whose edge lengths set the spacing (the garment as given).
    spacing : float, m
        Largest distance between neighbouring points along an edge.
    surface : bool
        False: the vertices only.

    Returns
    -------
    ContactPointSet
    """
    pos = np.asarray(rest_pos, dtype=np.float64)
    n = pos.shape[0]
    verts = [np.repeat(np.arange(n, dtype=np.int64)[:, None], 3, axis=1)]
    bary = [np.tile([1.0, 0.0, 0.0], (n, 1))]
    surface = bool(surface and len(face_offsets) > 1)
    if surface:
        tris = MeshData(pos, np.asarray(face_offsets, np.int64), np.asarray(face_verts, np.int64)).triangles()
        v, b = _edge_points(tris, pos, spacing)
        verts.append(v)
        bary.append(b)
        v, b = _interior_points(tris, pos, spacing)
        verts.append(v)
        bary.append(b)
        v, b = _quad_centres(face_verts, face_offsets)
        verts.append(v)
        bary.append(b)
    return ContactPointSet(np.ascontiguousarray(np.concatenate(verts), dtype=np.int64),
                           np.ascontiguousarray(np.concatenate(bary), dtype=np.float64), n,
                           float(spacing) if surface else 0.0)


def _edge_points(tris, pos, spacing):
    """Points inside every unique edge of the fan triangles, ``ceil(L / spacing) - 1`` per edge."""
    e = np.sort(np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]]), axis=1)
    e = np.unique(e, axis=0)
    length = np.linalg.norm(pos[e[:, 1]] - pos[e[:, 0]], axis=1)
    per = np.maximum(np.ceil(length / spacing).astype(np.int64), 1)
    count = per - 1
    edge = np.repeat(np.arange(e.shape[0]), count)
    k = np.arange(edge.size) - np.repeat(np.cumsum(count) - count, count) + 1
    t = k / per[edge]
    v = np.stack([e[edge, 0], e[edge, 1], e[edge, 0]], axis=1)
    b = np.stack([1.0 - t, t, np.zeros_like(t)], axis=1)
    return v, b


def _interior_points(tris, pos, spacing):
    """Interior points of each triangle's barycentric lattice of order ``ceil(L_max / spacing)``."""
    corners = pos[tris]
    longest = np.max(np.linalg.norm(corners - np.roll(corners, 1, axis=1), axis=2), axis=1)
    order = np.ceil(longest / spacing).astype(np.int64)
    vs, bs = [], []
    for m in np.unique(order[order >= 3]):
        ids = np.flatnonzero(order == m)
        lattice = np.array([(i, j, m - i - j) for i in range(1, m) for j in range(1, m - i)], float) / m
        vs.append(np.repeat(tris[ids], len(lattice), axis=0))
        bs.append(np.tile(lattice, (ids.size, 1)))
    if not vs:
        return np.zeros((0, 3), np.int64), np.zeros((0, 3))
    return np.concatenate(vs), np.concatenate(bs)


def _quad_centres(face_verts, face_offsets):
    """The midpoint of every quad's second diagonal (corners 1 and 3; the fan uses 0-2)."""
    fo = np.asarray(face_offsets, dtype=np.int64)
    fv = np.asarray(face_verts, dtype=np.int64)
    quads = np.flatnonzero(np.diff(fo) == 4)
    a, c = fv[fo[quads] + 1], fv[fo[quads] + 3]
    v = np.stack([a, c, a], axis=1)
    b = np.tile([0.5, 0.5, 0.0], (quads.size, 1))
    return v, b


def body_sag(body, points, contact):
    """(V,) m: the body's extra thickness at its small bumps (``ContactSettings.sag``) for the contact ``points``
    (a :class:`ContactPointSet`), from the body as it is now (a moving body's keeps it: its bumps move with it,
    their shapes barely change); (0,): none (no body, the setting off, or no surface points)."""
    if body is None or not contact.sag or not points.spacing > 0:
        return np.zeros(0)
    # the farthest a body point lies from the nearest point of the lattice; the points' own clearance
    # covers the rise up to it, and SAG_TOLERANCE more is left to cut in at worst
    return convex_sag(body.verts, body.tris, points.spacing / math.sqrt(3.0), contact.surface_skin + SAG_TOLERANCE)
