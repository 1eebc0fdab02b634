"""Horizontal sections of a body mesh and tape-measure girths.

:class:`MeshSections` holds the edge tables of one triangle topology and the scratch
buffers of the section kernels, so measuring any number of poses or shapes of the
same mesh costs only the kernels. A tape girth (ISO 8559-1 style, see
``shared/reference/MEASUREMENTS.md``) is the perimeter of the convex hull of the
torso loop of the horizontal section at height ``y``; ``method="spline"`` is the
seed system's profile-curve length and ``"polyline"`` the loop's own length
(which follows hollows a tape would bridge).

This module imports numba (through the kernels) and is meant for measurement
code only, never for the CLI's ``--help`` path.
"""
from typing import NamedTuple

import numpy as np

from vfit_engine.errors import InputError
from vfit_engine.kernels import girth as _kg
from vfit_engine.kernels import section as _ks

#: Girth methods accepted by :meth:`MeshSections.girth` and :meth:`MeshSections.scan`.
METHODS = {"hull": _kg.METHOD_HULL, "spline": _kg.METHOD_SPLINE, "polyline": _kg.METHOD_POLYLINE}

#: Spline evaluations per interval of the ``"spline"`` girth.
SPLINE_SAMPLES = 8

#: Most planes one :meth:`MeshSections.scan` may cut (1 mm over 100 m).
MAX_PLANES = 100_000

#: :meth:`MeshSections.scan`'s per-plane edge lists hold up to this many entries per mesh edge (a body's
#: 1 mm torso scans need under 1); longer lists fall back to testing every band edge at every plane.
PLANE_EDGES_PER_EDGE = 4


def rotation_to_y(n):
    """(3, 3) rotation taking the unit vector ``n`` to +Y (Rodrigues).

    Sections in any plane: rotate the vertices by it (``verts @ R.T``) and cut at the rotated
    height of a point of the plane with :meth:`MeshSections.loops`.
    """
    y = np.array([0.0, 1.0, 0.0])
    n = np.asarray(n, dtype=np.float64)
    c = float(np.dot(n, y))
    if c < 0.0:
        # 1 / (1 + c) loses all precision as n nears -Y (inf or NaN within ~1e-8 of it): turn -n,
        # which nears +Y, and then half a turn about X
        return np.diag([1.0, -1.0, -1.0]) @ rotation_to_y(-n)
    v = np.cross(n, y)
    vx = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + vx + vx @ vx / (1.0 + c)


class SectionScratch(NamedTuple):
    """The section kernels' scratch buffers for a mesh of E edges, in the order the kernels take them
    (:mod:`vfit_engine.kernels.section`, :mod:`vfit_engine.kernels.girth_grad`): a kernel that needs the first
    six takes ``*scratch[:6]``, one that needs all nine ``*scratch``. Their contents between calls mean nothing.
    """

    #: (E,) int64: candidate edges (those a plane or band cuts).
    cand: np.ndarray
    #: (E,) int64: per-edge visit marks of the loop walk.
    visited: np.ndarray
    #: (E,) int64: the edges cut at one plane.
    cut: np.ndarray
    #: (E, 2) float64, m: the loops' (x, z) points.
    pts: np.ndarray
    #: (E + 1,) int64: where each loop starts in ``pts``.
    loop_start: np.ndarray
    #: (E,) int64: 1 where the loop is closed.
    loop_closed: np.ndarray
    #: (E,) int64: the hull's sort order.
    order: np.ndarray
    #: (2 E + 1,) int64: the hull's points.
    hull: np.ndarray
    #: (SPLINE_WORK_ROWS, E + 1) float64: the spline girth's work rows.
    work: np.ndarray

    @classmethod
    def for_edges(cls, n_edges):
        """Buffers for a mesh of ``n_edges`` edges."""
        return cls(np.zeros(n_edges, dtype=np.int64), np.zeros(n_edges, dtype=np.int64),
                   np.zeros(n_edges, dtype=np.int64), np.zeros((n_edges, 2), dtype=np.float64),
                   np.zeros(n_edges + 1, dtype=np.int64), np.zeros(n_edges, dtype=np.int64),
                   np.zeros(n_edges, dtype=np.int64), np.zeros(2 * n_edges + 1, dtype=np.int64),
                   np.zeros((_kg.SPLINE_WORK_ROWS, n_edges + 1), dtype=np.float64))


class MeshSections:
    """Plane sections of one triangle topology.

    Parameters
    ----------
    tris : (T, 3) int
        Triangles indexing ``n_verts`` vertices. Triangles with a repeated vertex
        (zero area) are dropped; an edge shared by more than two triangles is an
        InputError (a section through it would be ambiguous).
    n_verts : int
        Number of vertices every ``verts`` passed later must have.

    Notes
    -----
    Not thread-safe: the instance owns the kernels' scratch buffers. Use one
    instance per thread.
    """

    def __init__(self, tris, n_verts):
        try:
            tris = np.asarray(tris)
        except (TypeError, ValueError) as exc:
            raise InputError(f"triangles are not an integer array: {exc}") from None
        if tris.ndim != 2 or tris.shape[1] != 3 or tris.shape[0] == 0:
            raise InputError(f"triangles must be a non-empty (T, 3) array, got shape {tris.shape}")
        if not np.issubdtype(tris.dtype, np.integer):
            raise InputError(f"triangles must be integers, got {tris.dtype}")
        n_verts = int(n_verts)
        if tris.min() < 0 or tris.max() >= n_verts:
            raise InputError(f"triangle indices must lie in [0, {n_verts}), got [{tris.min()}, {tris.max()}]")
        tris = tris.astype(np.int64)
        good = (tris[:, 0] != tris[:, 1]) & (tris[:, 1] != tris[:, 2]) & (tris[:, 2] != tris[:, 0])
        tris = np.ascontiguousarray(tris[good])
        if tris.shape[0] == 0:
            raise InputError("every triangle repeats a vertex")
        edges, tri_edges, edge_tris, counts = _ks.build_topology(tris)
        if counts.max() > 2:
            raise InputError(f"{int((counts > 2).sum())} edges are shared by more than two triangles "
                             "(non-manifold mesh)")
        self.n_verts = n_verts
        #: (T, 3) int64 triangles actually used (degenerate ones dropped).
        self.tris = tris
        #: (E, 2) int64 unique edges.
        self.edges = edges
        #: (T, 3) int64 triangle -> edge table.
        self.tri_edges = tri_edges
        #: (E, 2) int64 edge -> triangles table, -1 on a boundary.
        self.edge_tris = edge_tris
        #: The kernels' scratch buffers (:class:`SectionScratch`), for kernels called on this topology.
        self.scratch = SectionScratch.for_edges(edges.shape[0])
        self._plane_edges = None  # scan's per-plane edge lists, made at the first scan

    @property
    def edge_count(self):
        """Number of unique edges."""
        return self.edges.shape[0]

    def _verts(self, verts):
        verts = np.ascontiguousarray(verts, dtype=np.float64)
        if verts.shape != (self.n_verts, 3):
            raise InputError(f"vertices must have shape ({self.n_verts}, 3), got {verts.shape}")
        if not np.isfinite(verts).all():
            raise InputError("vertices contain NaN or infinite coordinates")
        return verts

    @staticmethod
    def _height(y, name="y"):
        try:
            y = float(y)
        except (TypeError, ValueError):
            raise InputError(f"{name} must be a number, got {y!r}") from None
        if not np.isfinite(y):
            raise InputError(f"{name} must be finite, got {y}")
        return y

    @staticmethod
    def _method(method):
        try:
            return METHODS[method]
        except (KeyError, TypeError):
            raise InputError(f"unknown girth method {method!r}; use one of {sorted(METHODS)}") from None

    def loops(self, verts, y, return_closed=False):
        """Ordered section loops at height ``y``.

        Parameters
        ----------
        verts : (n_verts, 3) float, m
        y : float, m
        return_closed : bool
            Also return, per loop, whether it is closed (False for a chain that
            runs into a mesh boundary).

        Returns
        -------
        loops : list of (k, 2) float64 arrays, m
            The (x, z) points of each loop in walk order, without a repeated end
            point. Consistent winding gives every loop the same orientation.
        closed : list of bool
            Only with ``return_closed``.
        """
        verts = self._verts(verts)
        y = self._height(y)
        sc = self.scratch
        n_pts, n_loops = _ks.section_at(verts, self.tris, self.edges, self.tri_edges, self.edge_tris, y,
                                        *sc[:6])
        starts = sc.loop_start[:n_loops + 1]
        loops = [sc.pts[starts[i]:starts[i + 1]].copy() for i in range(n_loops)]
        if return_closed:
            return loops, [bool(c) for c in sc.loop_closed[:n_loops]]
        return loops

    def apart(self, verts, ys):
        """(k,) bool: at each height ``ys`` (m), does the section show the torso and both arms apart - one
        loop across x = 0 and, wholly to either side of it, another loop? One kernel call; ``verts`` as in
        :meth:`girths` (a C-contiguous float64 array is used as it is)."""
        ys = np.ascontiguousarray(ys, dtype=np.float64).ravel()
        if verts.dtype != np.float64 or not verts.flags.c_contiguous or verts.shape != (self.n_verts, 3):
            verts = self._verts(verts)
        out = np.empty(ys.size, dtype=np.int64)
        _ks.apart_planes(verts, self.tris, self.edges, self.tri_edges, self.edge_tris, ys, *self.scratch[:6],
                         out)
        return out.astype(bool)

    def girth(self, verts, y, method="hull", x0=0.0):
        """Torso girth at height ``y``.

        Parameters
        ----------
        verts : (n_verts, 3) float, m
        y : float, m
        method : {"hull", "spline", "polyline"}
            Tape (convex hull perimeter), profile spline, or the loop's length.
        x0 : float, m
            x of the mid-sagittal plane; the torso loop is the largest loop whose
            x-range contains it (else the loop whose centroid is nearest).

        Returns
        -------
        float
            Girth, m; NaN when the plane misses the mesh.
        """
        _, g = self.scan(verts, y, y, method=method, x0=x0)
        return float(g[0])

    def girths(self, verts, ys, method="hull", x0=0.0):
        """Torso girths at arbitrary heights ``ys`` (m) in one kernel call (m; NaN where a plane
        misses the mesh). A C-contiguous float64 (n_verts, 3) ``verts`` is used as it is, without
        the finiteness check (the fast path for the morph solver's inner loop, whose bodies are
        finite by construction); anything else is validated like :meth:`scan`."""
        ys = np.ascontiguousarray(ys, dtype=np.float64).ravel()
        if verts.dtype != np.float64 or not verts.flags.c_contiguous or verts.shape != (self.n_verts, 3):
            verts = self._verts(verts)
        # ascending planes take the per-plane edge lists (one band selection for planes far apart too);
        # every plane's girth is the same bit for bit whatever the other planes
        order = np.argsort(ys, kind="stable")
        out = np.empty(ys.size, dtype=np.float64)
        out[order] = self._scan_sorted(verts, ys[order], self._method(method), float(x0))
        return out

    def _scan_sorted(self, verts, ys, code, x0):
        """Girths at the ascending planes ``ys`` (:func:`vfit_engine.kernels.section.scan_girths_sorted`)."""
        if self._plane_edges is None:  # per-plane edge lists: the edges of a 1 mm scan cut ~4 planes each
            self._plane_edges = np.zeros(PLANE_EDGES_PER_EDGE * self.edge_count, dtype=np.int64)
        out = np.empty(ys.size, dtype=np.float64)
        _ks.scan_girths_sorted(verts, self.tris, self.edges, self.tri_edges, self.edge_tris, ys, code,
                               SPLINE_SAMPLES, x0, *self.scratch, np.empty(ys.size + 1, dtype=np.int64),
                               self._plane_edges, out)
        return out

    def scan(self, verts, y_lo, y_hi, step=0.001, method="hull", x0=0.0):
        """Torso girths on evenly spaced planes from ``y_lo`` to ``y_hi`` (both included).

        The number of planes is ``ceil((y_hi - y_lo) / step) + 1``, so the actual
        spacing is at most ``step``. All planes are cut in one kernel call that tests
        only the edges overlapping the band.

        Parameters
        ----------
        verts : (n_verts, 3) float, m
        y_lo, y_hi : float, m
            ``y_lo <= y_hi``.
        step : float, m
            Largest plane spacing, > 0.
        method, x0 : as :meth:`girth`

        Returns
        -------
        ys : (k,) float64, m
        girths : (k,) float64, m
            NaN where a plane misses the mesh.
        """
        verts = self._verts(verts)
        y_lo = self._height(y_lo, "y_lo")
        y_hi = self._height(y_hi, "y_hi")
        step = self._height(step, "step")
        code = self._method(method)
        x0 = self._height(x0, "x0")
        if y_hi < y_lo:
            raise InputError(f"y_hi ({y_hi}) must not be below y_lo ({y_lo})")
        if step <= 0.0:
            raise InputError(f"step must be positive, got {step}")
        span = (y_hi - y_lo) / step
        if span > MAX_PLANES:
            raise InputError(f"scan of {span:.0f} planes exceeds the limit of {MAX_PLANES}")
        # the tolerance keeps e.g. 0.2 / 0.001 from becoming 201 intervals by rounding
        count = max(int(np.ceil(span - 1e-9)), 1) + 1 if y_hi > y_lo else 1
        ys = np.linspace(y_lo, y_hi, count)
        return ys, self._scan_sorted(verts, ys, code, x0)
