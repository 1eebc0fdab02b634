"""Mass-spring topology from polygons: springs, their area shares and vertex masses.

Polygons come as a flat ``face_verts`` (int64) with ``face_offsets`` (int64,
``m + 1`` entries, ``face_offsets[0] == 0``): face ``f`` is
``face_verts[face_offsets[f]:face_offsets[f + 1]]``. Triangles, quads and n-gons
may be mixed. Pure NumPy (no numba), so it is cheap to import.

Spring families (``spring_type`` codes):

``STRUCTURAL`` (0)  every unique polygon edge.
``SHEAR`` (1)       the diagonals of polygons with 4+ corners (for a quad: 0-2 and
                    1-3; for an n-gon: all n(n-3)/2 non-adjacent corner pairs).
``BEND`` (2)        across every interior edge (a, b) shared by exactly two faces,
                    one pair per end: at end ``a``, the neighbour of ``a`` in the
                    first face (other than ``b``) with the neighbour of ``a`` in the
                    second face. For two triangles both ends yield the same pair,
                    the two vertices opposite the edge, which serves as the bend
                    spring. For two quads the pairs are the second neighbours along
                    the grid rows/columns (i to i+2 through a and through b), so a
                    quad grid gets exactly the classic row/column bend springs.

Springs are deduplicated by their vertex pair; a pair already present in an
earlier family keeps that family (structural > shear > bend) and degenerate
pairs (i == j) are dropped.

Area share ``A_s`` of a spring (used to turn 2-D moduli into spring constants,
see :mod:`vfit_engine.sim.materials`):

* structural: sum over its faces of ``2 A_f / n_f`` (a quad-grid edge gets h^2);
* shear: ``A_f / n_diag`` of its face (a grid-quad diagonal gets h^2 / 2);
* bend: each interior edge hands ``(A_f1 + A_f2) / 2`` to the pair made at each of
  its ends, summed over all edges yielding the same pair (a grid bend pair gets
  2 h^2, the strip it spans).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vfit_engine.errors import InputError

STRUCTURAL = 0
SHEAR = 1
BEND = 2
SPRING_TYPE_NAMES = ("structural", "shear", "bend")


@dataclass(frozen=True, eq=False)
class SpringSet:
    """Springs of a polygon mesh.

    Attributes
    ----------
    indices : (s, 2) int64
        Vertex pairs, ``indices[:, 0] < indices[:, 1]``.
    rest : (s,) float64, m
        Rest lengths measured on the given positions.
    type : (s,) int64
        ``STRUCTURAL``, ``SHEAR`` or ``BEND``.
    area : (s,) float64, m^2
        Area share ``A_s`` (module docstring).
    """

    indices: np.ndarray
    rest: np.ndarray
    type: np.ndarray
    area: np.ndarray

    @property
    def count(self):
        return int(self.rest.shape[0])

    def count_of(self, spring_type):
        """Number of springs of one family."""
        return int(np.count_nonzero(self.type == spring_type))


def check_polygons(face_verts, face_offsets, vertex_count):
    """Validate and normalise a flat polygon list.

    Returns
    -------
    face_verts : (k,) int64
    face_offsets : (m + 1,) int64
    """
    fv = np.ascontiguousarray(face_verts, dtype=np.int64).ravel()
    fo = np.ascontiguousarray(face_offsets, dtype=np.int64).ravel()
    if fo.size < 1 or fo[0] != 0 or fo[-1] != fv.size:
        raise InputError("face_offsets must start at 0 and end at len(face_verts)")
    sizes = np.diff(fo)
    if np.any(sizes < 3):
        raise InputError("every polygon needs at least 3 vertices")
    if fv.size and (fv.min() < 0 or fv.max() >= vertex_count):
        raise InputError("face_verts refers to a vertex that does not exist")
    return fv, fo


def _check_pos(rest_pos):
    pos = np.ascontiguousarray(rest_pos, dtype=np.float64)
    if pos.ndim != 2 or pos.shape[1] != 3:
        raise InputError(f"positions must have shape (n, 3), got {pos.shape}")
    if not np.all(np.isfinite(pos)):
        raise InputError("positions contain NaN or infinity")
    return pos


def _corner_tables(fo):
    """Face, next-corner and previous-corner index of every corner."""
    sizes = np.diff(fo)
    face = np.repeat(np.arange(sizes.size, dtype=np.int64), sizes)
    local = np.arange(fo[-1], dtype=np.int64) - fo[face]
    nxt = fo[face] + (local + 1) % sizes[face]
    prv = fo[face] + (local - 1) % sizes[face]
    return face, local, nxt, prv


def polygon_areas(face_verts, face_offsets, rest_pos):
    """Area of every polygon by fan triangulation from its first corner.

    Parameters
    ----------
    face_verts : (k,) int64
    face_offsets : (m + 1,) int64
    rest_pos : (n, 3) float64, m

    Returns
    -------
    (m,) float64, m^2
    """
    pos = _check_pos(rest_pos)
    fv, fo = check_polygons(face_verts, face_offsets, pos.shape[0])
    face, local, nxt, _ = _corner_tables(fo)
    # fan triangles (first, c, next c) for every corner except the first and last
    fan = (local >= 1) & (nxt != fo[face])
    p0 = pos[fv[fo[face[fan]]]]
    p1 = pos[fv[fan]]
    p2 = pos[fv[nxt[fan]]]
    tri = 0.5 * np.linalg.norm(np.cross(p1 - p0, p2 - p0), axis=1)
    return np.bincount(face[fan], weights=tri, minlength=fo.size - 1)


def vertex_masses(face_verts, face_offsets, rest_pos, areal_density):
    """Lumped masses: each polygon's area x density shared equally by its corners.

    Parameters
    ----------
    face_verts : (k,) int64
    face_offsets : (m + 1,) int64
    rest_pos : (n, 3) float64, m
    areal_density : float, kg/m^2

    Returns
    -------
    (n,) float64, kg (0 for vertices in no polygon)
    """
    pos = _check_pos(rest_pos)
    fv, fo = check_polygons(face_verts, face_offsets, pos.shape[0])
    area = polygon_areas(fv, fo, pos)
    sizes = np.diff(fo)
    share = np.repeat(area / sizes, sizes)
    return np.bincount(fv, weights=share, minlength=pos.shape[0]) * float(areal_density)


def _pair_keys(a, b, n):
    lo = np.minimum(a, b)
    hi = np.maximum(a, b)
    return lo * n + hi


def build_springs(face_verts, face_offsets, rest_pos):
    """Structural, shear and bend springs of a polygon mesh (module docstring).

    Parameters
    ----------
    face_verts : (k,) int64
    face_offsets : (m + 1,) int64
    rest_pos : (n, 3) float64, m
        Positions at which the rest lengths are measured.

    Returns
    -------
    SpringSet
    """
    pos = _check_pos(rest_pos)
    n = pos.shape[0]
    fv, fo = check_polygons(face_verts, face_offsets, n)
    sizes = np.diff(fo)
    area_f = polygon_areas(fv, fo, pos)
    face, local, nxt, prv = _corner_tables(fo)

    # structural: half-edges c -> next(c), grouped by undirected key
    a, b = fv, fv[nxt]
    he_key = _pair_keys(a, b, n)
    s_keys, he_edge, he_count = np.unique(he_key, return_inverse=True, return_counts=True)
    he_edge = he_edge.ravel()
    s_area = np.bincount(he_edge, weights=2.0 * area_f[face] / sizes[face], minlength=s_keys.size)

    # shear: every non-adjacent corner pair of polygons with 4+ corners
    sh_a, sh_b, sh_w = [], [], []
    for size in np.unique(sizes[sizes >= 4]):
        fids = np.nonzero(sizes == size)[0]
        n_diag = size * (size - 3) // 2
        for p in range(size):
            for q in range(p + 2, size):
                if p == 0 and q == size - 1:
                    continue
                sh_a.append(fv[fo[fids] + p])
                sh_b.append(fv[fo[fids] + q])
                sh_w.append(area_f[fids] / n_diag)
    if sh_a:
        sh_key = _pair_keys(np.concatenate(sh_a), np.concatenate(sh_b), n)
        sh_w = np.concatenate(sh_w)
    else:
        sh_key = np.zeros(0, np.int64)
        sh_w = np.zeros(0)

    # bend: interior edges (exactly two half-edges)
    order = np.argsort(he_edge, kind="stable")
    starts = np.concatenate([[0], np.cumsum(he_count)])
    interior = np.nonzero(he_count == 2)[0]
    c1 = order[starts[interior]]
    c2 = order[starts[interior] + 1]
    # neighbour of the half-edge's start vertex (previous corner) and of its end (corner after next)
    start1, end1 = fv[prv[c1]], fv[nxt[nxt[c1]]]
    same = fv[c2] == fv[c1]  # second face walks the edge in the same direction (inconsistent winding)
    start2 = np.where(same, fv[prv[c2]], fv[nxt[nxt[c2]]])
    end2 = np.where(same, fv[nxt[nxt[c2]]], fv[prv[c2]])
    w_edge = 0.5 * (area_f[face[c1]] + area_f[face[c2]])
    bd_a = np.concatenate([start1, end1])
    bd_b = np.concatenate([start2, end2])
    bd_w = np.concatenate([w_edge, w_edge])
    keep = bd_a != bd_b
    bd_key = _pair_keys(bd_a[keep], bd_b[keep], n)
    bd_w = bd_w[keep]

    # deduplicate within each family (areas add), then across families by priority
    sh_keys, inv = np.unique(sh_key, return_inverse=True)
    sh_area = np.bincount(inv.ravel(), weights=sh_w, minlength=sh_keys.size)
    ok = ~np.isin(sh_keys, s_keys)
    sh_keys, sh_area = sh_keys[ok], sh_area[ok]
    bd_keys, inv = np.unique(bd_key, return_inverse=True)
    bd_area = np.bincount(inv.ravel(), weights=bd_w, minlength=bd_keys.size)
    ok = ~np.isin(bd_keys, s_keys) & ~np.isin(bd_keys, sh_keys)
    bd_keys, bd_area = bd_keys[ok], bd_area[ok]

    keys = np.concatenate([s_keys, sh_keys, bd_keys])
    indices = np.stack([keys // n, keys % n], axis=1).astype(np.int64)
    types = np.concatenate([np.full(s_keys.size, STRUCTURAL), np.full(sh_keys.size, SHEAR),
                            np.full(bd_keys.size, BEND)]).astype(np.int64)
    area = np.concatenate([s_area, sh_area, bd_area])
    rest = np.linalg.norm(pos[indices[:, 1]] - pos[indices[:, 0]], axis=1)
    return SpringSet(np.ascontiguousarray(indices), rest, types, area)


def spring_constants(springs, stiffness, damping):
    """Per-spring stiffness and damping from 2-D moduli (``k = K A_s / l0^2``).

    Parameters
    ----------
    springs : SpringSet
    stiffness : sequence of 3 float, N/m
        (structural, shear, bend) moduli, e.g. ``Material.stiffness``.
    damping : sequence of 3 float, N s/m
        (structural, shear, bend) viscosities, e.g. ``Material.damping``.

    Returns
    -------
    k : (s,) float64, N/m
    kd : (s,) float64, N s/m
    """
    stiffness = np.asarray(stiffness, dtype=np.float64)
    damping = np.asarray(damping, dtype=np.float64)
    if stiffness.shape != (3,) or damping.shape != (3,):
        raise InputError("stiffness and damping need one value per spring type (3)")
    rest = springs.rest
    if np.any(rest <= 0):
        i, j = springs.indices[int(np.argmax(rest <= 0))] + 1
        raise InputError(f"vertices {i} and {j} of the garment are at the same point (a spring between them would "
                         "have zero length): merge them or move one apart")
    scale = springs.area / (rest * rest)
    return stiffness[springs.type] * scale, damping[springs.type] * scale


def polygon_corners(face_verts, face_offsets):
    """The corners of polygons with 4 or more corners: (k, 3) int64 rows (previous, corner, next).

    Their angles are what shear changes (a triangle's angles are fixed by its three edges).
    """
    fv = np.asarray(face_verts, dtype=np.int64)
    fo = np.asarray(face_offsets, dtype=np.int64)
    face, _, nxt, prv = _corner_tables(fo)
    keep = np.diff(fo)[face] >= 4
    return np.ascontiguousarray(np.stack([fv[prv], fv, fv[nxt]], axis=1)[keep])


def grid_polygons(nx, ny, size_x=1.0, size_y=1.0, quads=True):
    """A flat rectangular grid in the XZ plane (y = 0), for tests and benchmarks.

    Vertex ``(i, j)`` (``i`` along x, ``j`` along z) has index ``j * nx + i``.

    Returns
    -------
    pos : (nx ny, 3) float64, m (centred on the origin)
    face_verts : (k,) int64
    face_offsets : (m + 1,) int64
    """
    xs = np.linspace(-0.5 * size_x, 0.5 * size_x, nx)
    zs = np.linspace(-0.5 * size_y, 0.5 * size_y, ny)
    gx, gz = np.meshgrid(xs, zs)
    pos = np.stack([gx.ravel(), np.zeros(nx * ny), gz.ravel()], axis=1)
    i, j = np.meshgrid(np.arange(nx - 1), np.arange(ny - 1))
    v00 = (j * nx + i).ravel()
    v10, v11, v01 = v00 + 1, v00 + nx + 1, v00 + nx
    if quads:
        fv = np.stack([v00, v01, v11, v10], axis=1).ravel()
        fo = np.arange(0, fv.size + 1, 4)
    else:
        fv = np.stack([v00, v01, v11, v00, v11, v10], axis=1).ravel()
        fo = np.arange(0, fv.size + 1, 3)
    return pos, fv.astype(np.int64), fo.astype(np.int64)
