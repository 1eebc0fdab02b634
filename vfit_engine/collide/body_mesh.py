"""Exact collider against a triangle mesh (the body): signed distance, projection, penetration.

Why a uniform grid rather than a BVH: cloth queries are all near the body and the
body's triangles are all about the same size (hm08: ~1 cm edges), the case a grid
answers from one cell with no tree descent: a point's own cell lists, ordered by
distance to the cell centre, every triangle within ``margin`` of it, and a cell-centre
signed distance per cell lets points well clear of the body (most cloth, most of the
time) be dismissed without touching a triangle. A BVH needs ~15 levels of box tests
per query for the same answer. The price is memory, paid once per body: for hm08 at
the default 9.8 mm cell, 0.9 M cells and 3.8 M list entries (74 MB), built in ~0.23 s
(:mod:`vfit_engine.kernels.collide_mesh_build`); :meth:`MeshCollider.refit` follows a
moving body for ~25 % less. See :mod:`vfit_engine.kernels.collide_mesh` for the search
and why it is exact.

The sign comes from the closest feature's angle-weighted pseudo-normal (Baerentzen &
Aanaes 2005): correct at faces, edges and vertices of a closed mesh, and local
(near a small hole it still follows the surrounding surface), which is what cloth
needs.
"""
from __future__ import annotations

import math

import numpy as np

from vfit_engine.errors import InputError
from vfit_engine.kernels import collide_mesh as K
from vfit_engine.kernels import collide_mesh_build as B
from vfit_engine.kernels import collide_mesh_empty as E
from vfit_engine.kernels.collide_mesh import project_points

#: Cell edge (m) of the automatic grid is this fraction of the mean triangle edge ...
_CELL_PER_EDGE = 1.0
#: ... enlarged until the dense grid has at most this many cells.
_MAX_CELLS = 8_000_000
#: Exact band of one cell, in cells (>= sqrt(3): see _layout).
_MARGIN_PER_CELL = 2.0


def as_points(a, name):
    """``a`` as (n, 3) float64 contiguous finite points, or an InputError naming it ``name``."""
    a = np.ascontiguousarray(a, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != 3:
        raise InputError(f"{name} must be an (n, 3) array, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise InputError(f"{name} contains NaN or infinite values")
    return a


def mesh_normals(verts, tris):
    """Face normals and the pseudo-normals of edges and vertices (Baerentzen & Aanaes 2005).

    Parameters
    ----------
    verts : (v, 3) float64, m
    tris : (t, 3) int64

    Returns
    -------
    tri_normals : (t, 3) float64
        Unit normals ``(b - a) x (c - a) / |...|`` (zero for a zero-area triangle).
    tri_edges : (t, 3) int64
        Edge index of (v0 v1), (v1 v2), (v2 v0) of each triangle.
    edge_normals : (e, 3) float64
        Normalised sum of the normals of the triangles sharing the edge.
    vert_normals : (v, 3) float64
        Normalised sum of the incident face normals, each weighted by the triangle's
        angle at the vertex.
    """
    verts = np.ascontiguousarray(verts, dtype=np.float64)
    tris = np.ascontiguousarray(tris, dtype=np.int64)
    tri_edges = np.empty_like(tris)
    edge_count = B.mesh_edges(tris, verts.shape[0], tri_edges)
    tri_normals, edge_normals, vert_normals = np.empty(tris.shape), np.empty((edge_count, 3)), np.empty(verts.shape)
    B.mesh_normals(verts, tris, tri_edges, tri_normals, edge_normals, vert_normals)
    return tri_normals, tri_edges, edge_normals, vert_normals


def morton_order(points):
    """Permutation sorting ``points`` (n, 3) along a Z-order curve (10 bits per axis)."""
    lo = points.min(axis=0)
    span = max(float(np.max(points.max(axis=0) - lo)), 1e-300)
    q = np.clip(((points - lo) / span * 1023.0).astype(np.int64), 0, 1023)
    code = np.zeros(len(points), dtype=np.int64)
    for bit in range(10):
        for ax in range(3):
            code |= ((q[:, ax] >> bit) & 1) << (3 * bit + ax)
    return np.argsort(code, kind="stable")


def pair_estimate(area, perimeter, count, reach, h):
    """Expected (cell, triangle) pairs of the grid, with room to spare: the cells whose centre lies
    within ``reach`` of a triangle fill its ``reach``-neighbourhood, of volume
    ``2 A r + (pi / 2) P r^2 + (4 / 3) pi r^3`` (Steiner's formula; A area, P perimeter), summed
    over the ``count`` triangles."""
    volume = 2.0 * area * reach + 0.5 * math.pi * perimeter * reach ** 2 + 4.0 / 3.0 * math.pi * reach ** 3 * count
    return int(1.1 * volume / h ** 3) + 16 * count + 1024


def _carve(arena, *parts):
    """Consecutive views ``(dtype, count)`` of the byte array ``arena``, each 8-byte aligned."""
    views, at = [], 0
    for dtype, count in parts:
        nbytes = np.dtype(dtype).itemsize * count
        views.append(arena[at:at + nbytes].view(dtype))
        at += -(-nbytes // 8) * 8
    return views


class MeshCollider:
    """Exact signed-distance collider against a triangle mesh.

    Parameters
    ----------
    verts : (n, 3) float64, m
        Mesh vertices (the body: the first 13,380 hm08 vertices).
    tris : (t, 3) int64
        Outward-wound triangles.
    skin : float, m
        Clearance that :meth:`project` keeps between particles and the surface.
    friction : float
        Coulomb coefficient of :meth:`project` (tangential change <= friction x normal change).
    restitution : float
        Coefficient of restitution of the normal velocity (0: inelastic).
    cell : float or None, m
        Grid cell edge; None picks the mean triangle edge (capped at 8 M cells).
    radius : float, m
        Search radius of :meth:`signed_distance`: distances with ``|d| < radius`` are
        exact, points farther away report ``d = +inf`` / ``-inf``.

    Attributes
    ----------
    grid : BodyGrid
        The body as the kernels take it (read-only; replaced by :meth:`update` and
        :meth:`refit`): :data:`vfit_engine.kernels.collide_mesh.BodyGrid`.
    margin : float, m
        A point's own cell holds its closest triangle whenever ``|d| <= margin``.
    cell_start : (ncells + 1,) int64;  cell_tris : (k,) int64
        Triangles of each cell (CSR; triangle indices in the grid's order).
    cell_sd : (ncells,) float64, m
        Signed distance of each cell centre (exact for cells with triangles; for empty
        cells a lower bound on its magnitude, with the sign of the cell's region).
    """

    def __init__(self, verts, tris, skin=0.003, friction=0.3, restitution=0.0, cell=None, radius=0.05, margin=None):
        tris = np.ascontiguousarray(tris, dtype=np.int64)
        if tris.ndim != 2 or tris.shape[1] != 3 or tris.shape[0] == 0:
            raise InputError(f"tris must be a non-empty (t, 3) array, got shape {tris.shape}")
        verts = as_points(verts, "verts")
        if tris.min() < 0 or tris.max() >= verts.shape[0]:
            raise InputError("tris index a vertex that does not exist")
        for name, value, lo in (("skin", skin, 0.0), ("friction", friction, 0.0), ("restitution", restitution, 0.0),
                                ("radius", radius, 0.0)):
            if not (math.isfinite(value) and value >= lo):
                raise InputError(f"{name} must be a finite number >= {lo}, got {value!r}")
        if restitution > 1.0:
            raise InputError(f"restitution must be in [0, 1], got {restitution!r}")
        if cell is not None and not (math.isfinite(cell) and cell > 0):
            raise InputError(f"cell must be a positive length in m, got {cell!r}")
        self.tris = tris
        self.skin = float(skin)
        self.friction = float(friction)
        self.restitution = float(restitution)
        self.radius = float(radius)
        if margin is not None and not (math.isfinite(margin) and margin > 0):
            raise InputError(f"margin must be a positive length in m, got {margin!r}")
        self._cell_request = cell
        self._margin_request = margin

        # the edge numbering depends on the triangles only: once per collider
        self.tri_edges = np.empty_like(tris)
        self._edge_count = B.mesh_edges(tris, verts.shape[0], self.tri_edges)
        self._vert_count = verts.shape[0]
        self._pool, self._keep_scratch, self._empty_ref = {}, False, None
        self.update(verts)

    # ------------------------------------------------------------------ build
    @property
    def grid(self):
        """The body as the kernels take it (:data:`vfit_engine.kernels.collide_mesh.BodyGrid`).

        A new tuple after every :meth:`update` / :meth:`refit`; its arrays are never modified
        afterwards, so a grid taken before a refit stays valid (for the old pose).
        """
        return self._grid

    def update(self, verts):
        """Rebuild everything for moved vertices (same triangles): triangle order, cell size, grid.

        ~0.23 s for the body (hm08); :meth:`refit` skips what the pose does not change.
        """
        verts = self._check_verts(verts)
        a, b, c = verts[self.tris[:, 0]], verts[self.tris[:, 1]], verts[self.tris[:, 2]]
        # kernels see the triangles in Z-order of their centroids, so the triangles of one
        # cell sit together in memory (queries are bound by memory latency, not arithmetic)
        self._set_order(morton_order((a + b + c) / 3.0))
        lo, hi = verts.min(axis=0), verts.max(axis=0)
        h = self._cell_request
        if h is None:
            edge = sum(float(np.sqrt(np.einsum("ij,ij->i", u - w, u - w)).sum()) for u, w in ((b, a), (c, b), (a, c)))
            h = max(_CELL_PER_EDGE * edge / (3 * len(a)), 1e-6 * float(np.max(hi - lo)), 1e-9)
        while True:
            margin, dims, origin = self._layout(lo, hi, h)
            if self._cell_request is not None or int(np.prod(dims)) <= _MAX_CELLS:
                break
            h *= (np.prod(dims) / _MAX_CELLS) ** (1.0 / 3.0) * 1.01
        self.cell, self.margin, self.dims, self.origin = float(h), margin, dims, origin
        self._fill(verts)

    def refit(self, verts):
        """Follow moved vertices (same triangles), keeping the triangle order, cell and margin.

        The grid box stays too while the mesh still fits in it with its empty border (a new box
        gets a cell to spare on each side), and while no vertex has moved more than a cell since
        the empty cells were last computed exactly, their bounds are those loosened by that
        distance instead of a new distance transform: ~25 % less than :meth:`update` for the
        body. Queries answer exactly as after :meth:`update` (the exact band does not depend on
        the grid); points beyond it are proven far a little less often, and the triangle order
        and cell size, chosen for the first pose, may suit the new one slightly less well.
        Replaces :attr:`grid` (fetch it again).

        Parameters
        ----------
        verts : (n, 3) float64, m
            New positions of the same vertices.
        """
        verts = self._check_verts(verts)
        self._keep_scratch = True
        lo, hi = verts.min(axis=0), verts.max(axis=0)
        h = self.cell
        # the outer layer of cells stays empty while the mesh keeps margin + 1.5 h from the box
        # faces (its centres are then beyond reach = margin + h*sqrt(3)/2)
        room = self.margin + 1.5 * h
        top = self.origin + self.dims * h
        if np.any(lo - self.origin < room) or np.any(top - hi < room):
            # a new box, with a cell to spare on each side for the next poses
            margin, dims, origin = self._layout(lo - h, hi + h, h)
            if self._cell_request is None and int(np.prod(dims)) > _MAX_CELLS:
                self.update(verts)  # spread too far for this cell: choose a new one
                return
            self.margin, self.dims, self.origin = margin, dims, origin
        self._fill(verts, exact_empty=False)

    def _check_verts(self, verts):
        verts = as_points(verts, "verts")
        if verts.shape[0] != self._vert_count:
            raise InputError(f"verts must have {self._vert_count} rows (the triangles' vertices), got {verts.shape[0]}")
        return verts

    def _set_order(self, order):
        self._tri_order = order
        self._grid_tris = np.ascontiguousarray(self.tris[order])
        self._grid_tri_edges = np.ascontiguousarray(self.tri_edges[order])

    def _layout(self, lo, hi, h):
        """``(margin, dims, origin)`` of a grid of cell ``h`` (m) around the box ``lo``-``hi``."""
        # margin >= h*sqrt(3): a point not resolved in its own cell is then farther than
        # h*sqrt(3)/2 from the cell centre's surface side, so the centre's sign is its sign;
        # 2h also makes the empty-region sign vote robust
        margin = max(_MARGIN_PER_CELL * h, self.skin, self._margin_request or 0.0)
        pad = margin + 2.0 * h  # the outer layer of cells stays empty
        dims = np.ascontiguousarray(np.ceil((hi - lo + 2.0 * pad) / h), dtype=np.int64)
        return float(margin), dims, np.ascontiguousarray(lo - pad, dtype=np.float64)

    def _fill(self, verts, exact_empty=True):
        """Normals, triangle records and the grid for ``verts`` on the current layout.

        ``exact_empty=False`` derives the empty cells from the last exact computation when the
        grid box is the same and no vertex has moved farther than a cell since
        (:func:`~vfit_engine.kernels.collide_mesh_empty.loosen_empty_sd`).
        """
        nt = self.tris.shape[0]
        tri_normals, edge_normals = np.empty((nt, 3)), np.empty((self._edge_count, 3))
        vert_normals = np.empty_like(verts)
        B.mesh_normals(verts, self.tris, self.tri_edges, tri_normals, edge_normals, vert_normals)
        self.verts, self.tri_normals = verts, tri_normals
        self.edge_normals, self.vert_normals = edge_normals, vert_normals
        tris = self._grid_tris
        tri_data = np.empty((nt, 16))
        area, perimeter = B.triangle_records(verts, tris, tri_data)

        h, margin, dims, origin = self.cell, self.margin, self.dims, self.origin
        ncells = int(np.prod(dims))
        if ncells >= 2 ** 31 - 1:  # the build's scratch indexes cells with int32
            raise InputError(f"a {h} m cell makes {ncells} grid cells, more than 2^31: choose a larger cell")
        half = 0.5 * math.sqrt(3.0) * h
        reach = margin + half + 1e-9 * float(np.max(verts.max(axis=0) - verts.min(axis=0)) + h)
        # one scratch arena: the pairs (9 bytes each, and a byte per pair for cell_lists), then
        # the empty-cell pass (18 bytes per cell); fresh memory is costly to touch (_scratch)
        cap = pair_estimate(area, perimeter, nt, reach, h)
        while True:
            arena = self._scratch("arena", max(10 * cap, 18 * ncells) + 64, np.uint8)
            cap = (arena.size - 64) // 10
            pair_cell, pair_tri, pair_level, level = _carve(arena, (np.int32, cap), (np.int32, cap), (np.uint8, cap),
                                                            (np.uint8, cap))
            n = B.bin_triangles(verts, tris, origin, dims, h, reach, pair_cell, pair_tri, pair_level)
            if n <= cap:
                break
            cap = n
        cell_start = np.empty(ncells + 1, dtype=np.int64)
        cell_tris, cell_tdist = np.empty(n, dtype=np.int64), np.empty(n)
        B.cell_lists(pair_cell[:n], pair_tri[:n], pair_level[:n], reach, cell_start, cell_tris, cell_tdist, level[:n])

        cell_sd = np.empty(ncells)
        grid = K.BodyGrid(tri_data, tris, np.ascontiguousarray(tri_normals[self._tri_order]), self._grid_tri_edges,
                          edge_normals, vert_normals, origin, dims, h, margin, cell_start, cell_tris, cell_tdist,
                          cell_sd, cell_sd)
        K.cell_centre_sd(np.flatnonzero(cell_start[1:] != cell_start[:-1]), grid, cell_sd)
        ref, delta = self._empty_ref, np.inf
        if not exact_empty and ref is not None and np.array_equal(ref[0], dims) and np.array_equal(ref[1], origin):
            delta = float(np.sqrt(np.max(np.einsum("ij,ij->i", verts - ref[2], verts - ref[2]))))
        if delta <= h:  # < (margin + half) / 2, as loosen_empty_sd needs
            # the slack covers the kernels' rounding many times over
            E.loosen_empty_sd(cell_start, ref[3], delta * (1.0 + 1e-9) + 1e-12, margin + half, cell_sd)
        else:
            d2, label, parent, band = _carve(arena, (np.float64, ncells), (np.int32, ncells), (np.int32, ncells),
                                             (np.uint8, ncells))
            E.empty_cell_sd(dims, h, margin, cell_start, cell_sd, band, label, parent, d2)
            self._empty_ref = (dims, origin, verts, cell_sd)  # cell_sd is never modified: no copy
        self.cell_start, self.cell_tris, self.cell_tdist, self.cell_sd = cell_start, cell_tris, cell_tdist, cell_sd
        self._grid = grid

    def _scratch(self, name, size, dtype):
        """At least ``size`` elements of scratch, kept for the next build once :meth:`refit` is used.

        First touches of fresh memory cost up to a third of a build on the benchmark machine (a
        virtual machine); a collider that is never refitted does not hold the scratch (~46 MB
        for hm08) between builds.
        """
        buf = self._pool.get(name)
        if buf is None or buf.size < size:
            buf = np.empty(size, dtype=dtype)
            if self._keep_scratch:
                self._pool[name] = buf
        return buf

    # ------------------------------------------------------------------ queries
    def query(self, points, max_out=None, max_in=None):
        """Closest point on the mesh, signed distance, outward normal and triangle of each point.

        Parameters
        ----------
        points : (n, 3) float64, m
        max_out, max_in : float, m, optional
            Exact for ``-max_in < d < max_out`` (both default to ``radius``); points
            proven beyond report ``d = +inf`` (outside) or ``-inf`` (inside), closest
            NaN, normal 0 and triangle -1.

        Returns
        -------
        d : (n,) float64, m
            Signed distance, negative inside.
        closest : (n, 3) float64, m
        normal : (n, 3) float64
            Unit outward direction: ``sign(d) (p - q) / |p - q|``, the closest feature's
            pseudo-normal when ``|d| < 1 nm``.
        tri : (n,) int64
        """
        points = as_points(points, "points")
        max_out = self.radius if max_out is None else float(max_out)
        max_in = self.radius if max_in is None else float(max_in)
        n = points.shape[0]
        d, closest, normal = np.empty(n), np.empty((n, 3)), np.empty((n, 3))
        tri = np.empty(n, dtype=np.int64)
        K.closest_points(points, self._grid, max_out, max_in, d, closest, normal, tri)
        hit = tri >= 0
        tri[hit] = self._tri_order[tri[hit]]
        return d, closest, normal, tri

    def signed_distance(self, points):
        """``(d (n,) m, closest (n, 3) m, normal (n, 3))`` within ``radius``; see :meth:`query`."""
        d, closest, normal, _ = self.query(points)
        return d, closest, normal

    def penetration(self, points):
        """How far ``points`` (n, 3) m are inside the mesh (inside: signed distance < 0).

        Returns
        -------
        dict
            ``max_depth_m`` (float, 0 if none inside), ``inside_count`` (int),
            ``inside_mask`` ((n,) bool) and ``depth_m`` ((n,) float64, 0 outside).
        """
        d, _, _, _ = self.query(points, max_out=0.0, max_in=np.inf)
        inside = d < 0.0
        depth = np.where(inside, -d, 0.0)
        return dict(max_depth_m=float(depth.max()) if depth.size else 0.0, inside_count=int(inside.sum()),
                    inside_mask=inside, depth_m=depth)

    # ------------------------------------------------------------------ cloth
    def project(self, x, x_prev, inv_mass, max_push=None):
        """Push particles closer than ``skin`` out to ``skin``, with restitution and friction (in place).

        A particle with ``inv_mass > 0`` and signed distance ``d < skin`` moves to
        ``q + skin * n`` (q closest point, n outward normal), by at most ``max_push``.
        The step's displacement ``v = x - x_prev`` is split along n: an approaching
        normal part becomes ``-restitution * vn``; the tangential part shrinks by
        ``friction * (vn' - vn)`` (Coulomb: friction bounded by the normal change; it is
        not a ``(1 - friction)`` factor) and never reverses. ``x_prev`` is set to
        ``x' - v'``, so the push itself adds no velocity. Inside particles are searched
        at any depth. Allocation-free: the kernel works particle by particle.

        Parameters
        ----------
        x, x_prev : (n, 3) float64 C-contiguous, m
            Positions and previous positions, updated in place.
        inv_mass : (n,) float64, 1/kg
            ``<= 0`` marks a pinned particle, never moved.
        max_push : float or None, m
            Longest correction per call (ramp it for garments that start inside); None: no limit.

        Returns
        -------
        int
            Number of particles corrected.
        """
        for name, a in (("x", x), ("x_prev", x_prev)):
            if not (isinstance(a, np.ndarray) and a.dtype == np.float64 and a.ndim == 2 and a.shape[1] == 3
                    and a.flags.c_contiguous and a.flags.writeable):
                raise InputError(f"{name} must be a writeable C-contiguous (n, 3) float64 array")
        if x_prev.shape != x.shape:
            raise InputError(f"x_prev has shape {x_prev.shape}, x has {x.shape}")
        if not (isinstance(inv_mass, np.ndarray) and inv_mass.dtype == np.float64 and inv_mass.shape == (x.shape[0],)
                and inv_mass.flags.c_contiguous):
            raise InputError(f"inv_mass must be a C-contiguous ({x.shape[0]},) float64 array")
        if max_push is None:
            max_push = np.inf
        elif not max_push > 0:
            raise InputError(f"max_push must be a positive length in m, got {max_push!r}")
        return project_points(x, x_prev, inv_mass, self._grid, self.skin, self.friction, self.restitution,
                              float(max_push), np.inf)


def empty_grid():
    """A body grid with no triangles: the cloth kernels' argument when there is no body mesh."""
    z3, zi = np.zeros((0, 3)), np.zeros((0, 3), np.int64)
    return K.BodyGrid(np.zeros((0, 16)), zi, z3, zi, z3, z3, np.zeros(3), np.ones(3, np.int64), 1.0, 1.0,
                    np.zeros(2, np.int64), np.zeros(0, np.int64), np.zeros(0), np.zeros(1))
