"""Exact collider of a body that moves: one grid per animation frame, the surface where it is at every substep.

An animated body moves a lot in a frame (a walking shin 10 cm in 1/30 s), and the cloth must meet it where
it is at each substep, not where it was at the frame's start. Rebuilding the still body's grid
(:class:`~vfit_engine.collide.body_mesh.MeshCollider`) at every substep would cost ~0.25 s each. Instead,
over one *interval* (a frame: the body goes from pose ``v0`` to pose ``v1``, each vertex on the straight line
between them):

* the grid's lists are made once for the whole interval (:func:`~vfit_engine.kernels.collide_mesh_sweep.
  bin_swept`): a triangle is listed in every cell whose centre it comes within ``reach`` of at any time of
  the interval, binned along its path in pieces, so a slow triangle costs what it does on a still body and a
  fast one a tube along its path; the lists' distance floors are lower bounds over the interval;
* at each substep :meth:`MovingBodyCollider.at` puts the triangles' records and pseudo-normals where the body
  is at that time (in place: the solver's grid sees them), ~1 ms;
* the cells' centre distances are bounds over the interval (``BodyGrid.cell_sd`` / ``cell_sd_hi``): a cell
  with triangles has none (the search finds the closest triangle, exactly), an empty cell has none of its
  triangles within ``reach`` during the interval and keeps its side of the body, which is carried from
  interval to interval (:func:`~vfit_engine.kernels.collide_mesh_sweep.carry_signs`) instead of a distance
  transform, and settled by an exact query where nothing carries it.

So every query at any time of the interval is exact, as on a still body (the same search,
:func:`vfit_engine.kernels.collide_mesh.query_point`); points well clear of the body are dismissed a
little less often (no distance transform: an empty cell's bound is ``reach``).

The grid box is fixed for the motion: give it the box of all its poses (``box``).
"""
from __future__ import annotations

import math
import time

import numpy as np

from vfit_engine.collide.body_mesh import as_points, morton_order, pair_estimate
from vfit_engine.errors import InputError
from vfit_engine.kernels import collide_mesh as K
from vfit_engine.kernels import collide_mesh_build as B
from vfit_engine.kernels import collide_mesh_empty as E
from vfit_engine.kernels import collide_mesh_sweep as S

#: Cell edge of the automatic grid: the mean triangle edge (as the still body's).
_CELL_PER_EDGE = 1.4
#: The exact band of a cell, in cells: a point's own cell answers it within ``margin`` of the surface
#: (:data:`vfit_engine.kernels.collide_mesh.BodyGrid`); smaller than the still body's 2 cells, since the lists
#: are made every frame (``benchmarks/bench_moving_body.py``).
MARGIN_PER_CELL = 0.7
#: Longest move of a vertex within one piece of the binning, in cells.
PIECE_PER_CELL = 1.0


class MovingBodyCollider:
    """Exact signed-distance collider of a triangle mesh moving from pose to pose (module docstring).

    Parameters
    ----------
    verts : (n, 3) float64, m
        The first pose.
    tris : (t, 3) int64
        Outward-wound triangles of a closed surface.
    box : ((3,), (3,)) float64, m, or None
        Lowest and highest corner of every pose the body will take; None: the first pose's box.
    active : (t,) bool or None
        The triangles the cloth collides with (None: all): e.g. those within some centimetres of a garment
        (:func:`vfit_engine.animate.colliders.near_triangles`); the others cost nothing per frame. The side of
        the body empty cells are on is taken from the whole surface at the first pose, so the interior of a
        part cut off where the active triangles end stays inside
        (see :func:`~vfit_engine.kernels.collide_mesh_sweep.carry_signs`).
    cell, margin, piece : float, m, or None
        Grid cell edge (None: the mean edge of the active triangles), the exact band of a cell (None:
        :data:`MARGIN_PER_CELL` cells) and the longest move of a vertex within one piece of the binning
        (None: :data:`PIECE_PER_CELL` cells).

    Attributes
    ----------
    grid : BodyGrid
        The body as the kernels take it: a new tuple after each :meth:`advance`; its triangle records and
        normals are rewritten in place by :meth:`at`.
    s : float
        The time within the interval (0 at its start pose, 1 at its end) the grid's geometry is at.
    moved : float, m
        How far the surface moved at most in the last :meth:`at` (:meth:`SolverVerlet.body_moved
        <vfit_engine.sim.solver_verlet.SolverVerlet.body_moved>` takes it).
    timings : dict
        Seconds spent in :meth:`advance` (``bin``, ``lists``, ``sides``) and :meth:`at` (``pose``) so far.
    """

    def __init__(self, verts, tris, box=None, active=None, cell=None, margin=None, piece=None):
        tris = np.ascontiguousarray(tris, dtype=np.int64)
        verts = as_points(verts, "verts")
        if tris.ndim != 2 or tris.shape[1] != 3 or tris.shape[0] == 0:
            raise InputError(f"tris must be a non-empty (t, 3) array, got shape {tris.shape}")
        if tris.min() < 0 or tris.max() >= verts.shape[0]:
            raise InputError("tris index a vertex that does not exist")
        active = np.ones(len(tris), bool) if active is None else np.asarray(active, dtype=bool)
        if active.shape != (len(tris),) or not active.any():
            raise InputError(f"active must be ({len(tris)},) bool with at least one triangle")
        self.active = active
        all_tris = tris
        tris = np.ascontiguousarray(tris[active])
        a, b, c = verts[tris[:, 0]], verts[tris[:, 1]], verts[tris[:, 2]]
        if cell is None:
            edge = sum(float(np.sqrt(np.einsum("ij,ij->i", u - w, u - w)).sum()) for u, w in ((b, a), (c, b), (a, c)))
            cell = _CELL_PER_EDGE * edge / (3 * len(a))
        h = float(cell)
        self.cell = h
        self.margin = float(MARGIN_PER_CELL * h if margin is None else margin)
        self.piece = float(PIECE_PER_CELL * h if piece is None else piece)
        for name, value in (("cell", h), ("margin", self.margin), ("piece", self.piece)):
            if not (math.isfinite(value) and value > 0):
                raise InputError(f"{name} must be a positive length in m, got {value!r}")
        half = 0.5 * math.sqrt(3.0) * h
        self.reach = self.margin + half
        lo, hi = (verts.min(axis=0), verts.max(axis=0)) if box is None else (np.asarray(box[0], float),
                                                                            np.asarray(box[1], float))
        pad = self.reach + self.piece + 2.0 * h  # the outer layer of cells stays empty
        self.dims = np.ascontiguousarray(np.ceil((hi - lo + 2.0 * pad) / h), dtype=np.int64)
        self.origin = np.ascontiguousarray(lo - pad, dtype=np.float64)
        ncells = int(np.prod(self.dims))
        if ncells >= 2 ** 31 - 1:
            raise InputError(f"a {h} m cell makes {ncells} grid cells for this motion's box: choose a larger cell")
        self.ncells = ncells
        # kernels see the triangles in Z-order of their centroids (as the still body's grid)
        order = morton_order((a + b + c) / 3.0)
        self._tri_order = np.flatnonzero(active)[order]  # grid triangle -> triangle of ``tris``
        self.tris = all_tris
        self._grid_tris = np.ascontiguousarray(tris[order])
        tri_edges = np.empty_like(tris)
        edge_count = B.mesh_edges(tris, verts.shape[0], tri_edges)
        self._grid_tri_edges = np.ascontiguousarray(tri_edges[order])
        nt = tris.shape[0]
        self._angles = np.empty((nt, 3))
        self._tri_move = np.zeros(nt)
        self._tri_data, self._tri_normals = np.zeros((nt, 16)), np.empty((nt, 3))
        self._edge_normals, self._vert_normals = np.empty((edge_count, 3)), np.empty_like(verts)
        self.verts = verts.copy()
        self._v0, self._v1 = verts.copy(), verts.copy()
        self._verts_used = np.ascontiguousarray(np.unique(tris), dtype=np.int64)
        # a coarse field of how far the surface moved in the last step: a cell's value covers every point
        # within ``field_cell`` of it (its 26 neighbours are in it), more than a contact point's reach plus
        # a triangle (SolverVerlet.body_moved looks points up in it)
        longest = float(max(np.linalg.norm(u - w, axis=1).max() for u, w in ((b, a), (c, b), (a, c))))
        self.field_cell = longest + 0.04
        self._field = np.zeros(tuple(np.maximum(np.ceil(self.dims * h / self.field_cell).astype(int), 1)))
        self._field_max = np.zeros_like(self._field)
        # per cell: the side of an empty cell's centre (+1 / -1), whether the last interval listed it
        self._side = np.empty(ncells, dtype=np.int8)
        self._listed = np.zeros(ncells, dtype=np.bool_)
        self._lo, self._hi = np.empty(ncells), np.empty(ncells)
        self._cell_start = np.empty(ncells + 1, dtype=np.int64)
        self._stamp, self._slot = np.empty(ncells, dtype=np.int32), np.empty(ncells, dtype=np.int32)
        self._queue = np.empty(ncells, dtype=np.int64)
        area = float(0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1).sum())
        perimeter = float(sum(np.linalg.norm(u - w, axis=1).sum() for u, w in ((b, a), (c, b), (a, c))))
        self._cap = pair_estimate(area, perimeter, nt, self.reach + self.piece, h)
        self._pairs = None
        self._cells = None
        self.timings = dict(bin=0.0, lists=0.0, sides=0.0, pose=0.0)
        self.intervals = 0
        self.queried_sides = 0
        self.s, self.moved = 0.0, 0.0
        self._exact_at = None
        self._start(verts, all_tris)

    # ------------------------------------------------------------------ intervals
    def _start(self, verts, all_tris):
        """The still first pose: every empty cell's side from the whole surface (a sign vote over its region,
        as a still body's grid), then the active triangles' lists and the sides of the cells only the whole
        surface listed."""
        self._whole_sides(verts, all_tris)
        self._bin(verts, verts)
        self._geometry(0.0)
        self._sides()
        self._bounds()
        self.queried_sides = 0
        self.timings = dict.fromkeys(self.timings, 0.0)

    def _whole_sides(self, verts, tris):
        """:attr:`_side` and :attr:`_listed` of the whole surface ``tris`` at ``verts``, still."""
        nt, nv, ncells = len(tris), len(verts), self.ncells
        tri_edges = np.empty_like(tris)
        ne = B.mesh_edges(tris, nv, tri_edges)
        tn, en, vn = np.empty((nt, 3)), np.empty((ne, 3)), np.empty((nv, 3))
        B.mesh_normals(verts, tris, tri_edges, tn, en, vn)
        tri_data = np.empty((nt, 16))
        area, perimeter = B.triangle_records(verts, tris, tri_data)
        cap = pair_estimate(area, perimeter, nt, self.reach, self.cell)
        while True:
            pair_cell, pair_tri, level = np.empty(cap, np.int32), np.empty(cap, np.int32), np.empty(cap, np.uint8)
            n = B.bin_triangles(verts, tris, self.origin, self.dims, self.cell, self.reach, pair_cell, pair_tri, level)
            if n <= cap:
                break
            cap = n
        cell_start, cell_tris, cell_tdist = np.empty(ncells + 1, np.int64), np.empty(n, np.int64), np.empty(n)
        B.cell_lists(pair_cell[:n], pair_tri[:n], level[:n], self.reach, cell_start, cell_tris, cell_tdist,
                     np.empty(n, np.uint8))
        sd = np.empty(ncells)
        grid = K.BodyGrid(tri_data, tris, tn, tri_edges, en, vn, self.origin, self.dims, self.cell, self.margin,
                          cell_start, cell_tris, cell_tdist, sd, sd)
        listed = cell_start[1:] != cell_start[:-1]
        K.cell_centre_sd(np.flatnonzero(listed), grid, sd)
        E.empty_cell_sd(self.dims, self.cell, self.margin, cell_start, sd, np.empty(ncells, np.uint8),
                        np.empty(ncells, np.int32), np.empty(ncells, np.int32), np.empty(ncells))
        np.copyto(self._side, np.where(sd < 0.0, -1, 1).astype(np.int8))
        np.copyto(self._listed, listed)

    def advance(self, verts_next):
        """Start the next interval: from the pose the last one ended at (or the first) to ``verts_next``.

        Makes the interval's lists, carries the empty cells' sides, bounds the centre distances of the cells
        near the surface over the interval and puts the geometry at the interval's start (``s = 0``).
        Replaces :attr:`grid`.
        """
        verts_next = as_points(verts_next, "verts")
        if verts_next.shape != self._v1.shape:
            raise InputError(f"verts must have shape {self._v1.shape}, got {verts_next.shape}")
        lo, hi = self.origin, self.origin + self.dims * self.cell
        room = self.reach + self.piece + self.cell
        if np.any(verts_next.min(axis=0) - lo < room) or np.any(hi - verts_next.max(axis=0) < room):
            raise InputError("the body left the grid's box: give MovingBodyCollider the box of the whole motion")
        np.copyto(self._v0, self._v1)
        np.copyto(self._v1, verts_next)
        self._bin(self._v0, self._v1)
        self._geometry(0.0)
        t0 = time.perf_counter()
        self._sides()
        self._bounds()
        S.listed_bounds(self._grid, self._tri_move, self.reach, self._lo, self._hi)
        self.timings["sides"] += time.perf_counter() - t0
        self.intervals += 1

    def _bin(self, v0, v1):
        """The lists of the interval ``v0`` -> ``v1`` and a new :attr:`grid` (its geometry not yet set)."""
        t0 = time.perf_counter()
        while True:
            if self._pairs is None or self._pairs[0].size < self._cap:
                self._pairs = (np.empty(self._cap, np.int32), np.empty(self._cap, np.int32),
                               np.empty(self._cap, np.uint8), np.empty(self._cap, np.uint8))
            cell, tri, level, scratch = self._pairs
            n = S.bin_swept(v0, v1, self._grid_tris, self.origin, self.dims, self.cell, self.reach, self.piece,
                            self._stamp, self._slot, cell, tri, level, self._tri_move)
            if n <= cell.size:
                break
            self._cap = int(1.2 * n)
        t1 = time.perf_counter()
        if self._cells is None or self._cells[0].size < n:
            self._cells = (np.empty(int(1.2 * n), np.int64), np.empty(int(1.2 * n)))
        cell_tris, cell_tdist = self._cells[0][:n], self._cells[1][:n]
        B.cell_lists(cell[:n], tri[:n], level[:n], self.reach + 0.5 * self.piece, self._cell_start, cell_tris,
                     cell_tdist, scratch[:n])
        self._grid = K.BodyGrid(self._tri_data, self._grid_tris, self._tri_normals, self._grid_tri_edges,
                                self._edge_normals, self._vert_normals, self.origin, self.dims, self.cell,
                                self.margin, self._cell_start, cell_tris, cell_tdist, self._lo, self._hi)
        self.timings["bin"] += t1 - t0
        self.timings["lists"] += time.perf_counter() - t1

    def _sides(self):
        """The side of every empty cell of the new interval (carried, else queried at the interval's start)."""
        left = S.carry_signs(self.dims, self._cell_start, self._listed, self._side, self._queue)
        if left:
            empty = self._cell_start[1:] == self._cell_start[:-1]
            cells = np.flatnonzero(empty & (self._side == 0))
            ny, nz = self.dims[1], self.dims[2]
            ijk = np.stack([cells // (ny * nz), (cells // nz) % ny, cells % nz], axis=1)
            centres = np.ascontiguousarray(self.origin + (ijk + 0.5) * self.cell)
            self._lo[cells], self._hi[cells] = -np.inf, np.inf  # no bound: the search goes until it finds
            d, q, nrm = np.empty(len(cells)), np.empty((len(cells), 3)), np.empty((len(cells), 3))
            K.closest_points(centres, self._grid, np.inf, np.inf, d, q, nrm, np.empty(len(cells), np.int64))
            self._side[cells] = np.where(d < 0.0, -1, 1)
            self.queried_sides += len(cells)
        np.not_equal(self._cell_start[1:], self._cell_start[:-1], out=self._listed)

    def _bounds(self):
        """``cell_sd`` / ``cell_sd_hi``: no bound for listed cells, ``reach`` on their side for empty ones."""
        S.cell_bounds(self._cell_start, self._side, self.reach, self._lo, self._hi)
        self._exact_at = None

    # ------------------------------------------------------------------ substeps
    def _geometry(self, s):
        """The corner angles at the interval's start, then the geometry at ``s``."""
        S.corner_angles(self._v0, self._grid_tris, self._angles)
        self.at(s)

    def at(self, s):
        """Put the surface where it is at time ``s`` (0..1) of the interval: the triangles' records and the
        pseudo-normals, in place. Sets :attr:`moved` to how far it moved since the last call (m)."""
        t0 = time.perf_counter()
        s = float(min(max(s, 0.0), 1.0))
        if self._exact_at is not None:  # the exact centre distances held at one time only
            self._bounds()
            self._exact_at = None
        self.moved = S.pose_records(self._v0, self._v1, s, self._verts_used, self._grid_tris, self.verts,
                                    self._tri_data, self.origin, self.field_cell, self._field)
        S.dilate_max(self._field, self._field_max)
        S.pose_normals(self.verts, self._grid_tris, self._grid_tri_edges, self._angles, self._tri_normals,
                       self._edge_normals, self._vert_normals)
        self.s = s
        self.timings["pose"] += time.perf_counter() - t0

    def motion_bound(self, points):
        """(k,) m: how far the surface within ``field_cell`` of each of ``points`` (k, 3) m moved at most in the
        last :meth:`at` (the largest move anywhere for points off the grid)."""
        p = np.ascontiguousarray(points, dtype=np.float64)
        out = np.empty(len(p))
        S.field_lookup(p, self.origin, self.field_cell, self._field_max, self.moved, out)
        return out

    def settle_bounds(self):
        """Exact centre distances for the cells with triangles, at the surface's current time (m): queries then
        dismiss points well clear of (or deep in) the body as a still body's grid does. Valid until the
        surface moves again (the next :meth:`at` or :meth:`advance`, which put the interval's bounds back)."""
        S.listed_centre_sd(self._grid, self.reach, self._lo, self._hi)
        self._exact_at = self.s

    @property
    def grid(self):
        """The body as the kernels take it (:data:`vfit_engine.kernels.collide_mesh.BodyGrid`)."""
        return self._grid

    # ------------------------------------------------------------------ queries
    def query(self, points, max_out=0.05, max_in=0.05):
        """Closest point, signed distance, outward normal and triangle of each point, against the surface at
        the current time (:meth:`vfit_engine.collide.body_mesh.MeshCollider.query`)."""
        points = as_points(points, "points")
        n = points.shape[0]
        d, closest, normal = np.empty(n), np.empty((n, 3)), np.empty((n, 3))
        tri = np.empty(n, dtype=np.int64)
        K.closest_points(points, self._grid, float(max_out), float(max_in), d, closest, normal, tri)
        hit = tri >= 0
        tri[hit] = self._tri_order[tri[hit]]
        return d, closest, normal, tri

    def penetration(self, points):
        """How far ``points`` are inside the surface now (:meth:`MeshCollider.penetration
        <vfit_engine.collide.body_mesh.MeshCollider.penetration>`)."""
        d, _, _, _ = self.query(points, max_out=0.0, max_in=np.inf)
        inside = d < 0.0
        depth = np.where(inside, -d, 0.0)
        return dict(max_depth_m=float(depth.max()) if depth.size else 0.0, inside_count=int(inside.sum()),
                    inside_mask=inside, depth_m=depth)
