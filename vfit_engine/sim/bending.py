"""Bending of cloth: dihedral hinges whose stiffness comes from the fabric's bending rigidity.

A cloth of bending rigidity ``B`` (N m: moment per unit width per unit curvature) bent into a cylinder
of curvature ``kappa`` stores ``B kappa^2 / 2`` per unit area. Its triangles meet at hinges (an interior
edge ``e`` between triangles of areas ``A0``, ``A1``) whose bend angle ``theta`` is about ``kappa`` times
the distance between the triangles' centroids across ``e``; the discrete-shells energy (Grinspun et al.
2003) sums ``k (theta - theta0)^2 / 2`` with::

    k = B |e|^2 / (A0 + A1)

which makes the sum ``B kappa^2 / 2`` per unit area on any mesh of near-equilateral triangles at any
spacing and for any direction of the bend: measured on cylinders, 0.98-1.03 of ``B kappa^2 / 2`` on
hexagonal and jittered meshes at every bend direction (``tests/test_bending.py``). A grid of right
triangles is exact along its rows and columns and stiffer across its diagonals (a mesh's own
anisotropy: up to 2.9x at 45 degrees with every diagonal one way); a quad is therefore split both
ways, each triangulation with half the stiffness (at most 2x at 45 degrees on a regular quad grid;
bends along the grid lines, and every bend of a triangle mesh, are exact). The kernel is
:mod:`vfit_engine.kernels.bending`.

``theta0`` is the garment's own angle at the hinge: the cloth resists bending away from the shape it
was made in (a sleeve is a tube, a turned hem stays turned), as a pressed and sewn garment does; a
flat specimen has ``theta0 = 0``.

A woven bends differently along warp and weft (KES-F measures both). With UVs laid out as a sewing
pattern (:func:`uv_is_pattern`), warp follows the V axis and weft the U axis: a hinge whose edge runs
along U curves the cloth along V, the warp, and ``B = B_warp cos^2 phi + B_weft sin^2 phi`` with ``phi``
the angle of its edge to U. Without such UVs the cloth is isotropic with the mean of the two.

Shapes::

    build_hinges(face_verts (k,), face_offsets (m+1,), rest (n, 3), rigidity (2,), uv=None) -> Hinges
    hinge_angles(indices (h, 4), pos (n, 3)) -> (h,) rad
    hinge_gradient_norms(indices (h, 4), pos (n, 3)) -> (h, 4) 1/m
    bending_energy(hinges, pos (n, 3)) -> J
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: Triangles thinner than this (area / longest edge^2) carry no hinge: their normal is noise.
MIN_ASPECT = 1e-4
#: UVs are a sewing pattern when this share of the triangles maps to UV at one scale and near
#: conformally (:func:`uv_is_pattern`).
PATTERN_SHARE = 0.9


@dataclass(frozen=True, eq=False)
class Hinges:
    """Bending hinges of a cloth.

    Attributes
    ----------
    indices : (h, 4) int64
        Edge ends, then the vertex opposite the edge in each triangle.
    k : (h,) float64, N m / rad^2
    kd : (h,) float64, N m s / rad^2
    rest_angle : (h,) float64, rad
    anisotropic : bool
        Warp and weft follow the UVs (else the cloth is isotropic).
    """

    indices: np.ndarray
    k: np.ndarray
    kd: np.ndarray
    rest_angle: np.ndarray
    anisotropic: bool = False

    @property
    def count(self):
        return int(self.k.shape[0])


def _triangulations(fv, fo):
    """The polygons as triangles ((T, 3) int64 each), one triangulation or two: triangles as given, larger
    polygons as a fan from their first corner, and each quad split along one diagonal in the first
    triangulation and along the other in the second (only when there are quads)."""
    sizes = np.diff(fo)
    first, second = [], []
    for size in np.unique(sizes):
        corners = fv[fo[:-1][sizes == size][:, None] + np.arange(size)]
        if size == 4:
            first += [corners[:, [0, 1, 2]], corners[:, [0, 2, 3]]]
            second += [corners[:, [1, 2, 3]], corners[:, [1, 3, 0]]]
        else:
            fan = [corners[:, [0, t, t + 1]] for t in range(1, size - 1)]
            first += fan
            second += fan
    first = np.concatenate(first)
    return [first] if not np.any(sizes == 4) else [first, np.concatenate(second)]


def _hinges_of(tris, n):
    """(h, 4) int64: the hinges of a triangle mesh (edge ends, opposite vertices) at its interior
    edges; boundary and non-manifold edges carry none."""
    a, b, o = tris.ravel(), np.roll(tris, -1, axis=1).ravel(), np.roll(tris, -2, axis=1).ravel()
    key = np.minimum(a, b) * n + np.maximum(a, b)
    order = np.argsort(key, kind="stable")
    k_sorted = key[order]
    start = np.flatnonzero(np.r_[True, k_sorted[1:] != k_sorted[:-1]])
    count = np.diff(np.r_[start, k_sorted.size])
    two = start[count == 2]
    h1, h2 = order[two], order[two + 1]
    return np.stack([a[h1], b[h1], o[h1], o[h2]], axis=1)


def hinge_angles(indices, pos):
    """(h,) float64, rad: the signed bend angle of every hinge at ``pos`` (0 flat)."""
    x0, x1, x2, x3 = (pos[indices[:, m]] for m in range(4))
    e = x1 - x0
    n0, n1 = np.cross(e, x2 - x0), np.cross(x3 - x0, e)
    le = np.linalg.norm(e, axis=1)
    s = np.einsum("ij,ij->i", np.cross(n0, n1), e) / np.where(le > 0, le, 1.0)
    return np.arctan2(s, np.einsum("ij,ij->i", n0, n1))


def hinge_gradient_norms(indices, pos):
    """(h, 4) float64, 1/m: |d theta / d x_m| of each hinge's vertices m = 0..3 at ``pos`` (the gradient of
    :mod:`vfit_engine.kernels.bending`); the solver's stability bound on a hinge is built from them."""
    x0, x1, x2, x3 = (pos[indices[:, k]] for k in range(4))
    e = x1 - x0
    le = np.maximum(np.linalg.norm(e, axis=1), 1e-300)
    n0, n1 = np.cross(e, x2 - x0), np.cross(x3 - x0, e)
    g2 = -(le / np.maximum(np.sum(n0 * n0, 1), 1e-300))[:, None] * n0
    g3 = -(le / np.maximum(np.sum(n1 * n1, 1), 1e-300))[:, None] * n1
    t2 = np.einsum("ij,ij->i", x2 - x0, e) / le ** 2
    t3 = np.einsum("ij,ij->i", x3 - x0, e) / le ** 2
    g1 = -t2[:, None] * g2 - t3[:, None] * g3
    return np.stack([np.linalg.norm(g, axis=1) for g in (-(g1 + g2 + g3), g1, g2, g3)], axis=1)


def uv_is_pattern(tris, tri_uvs, uvs, pos):
    """Whether the UVs are laid out as a sewing pattern: ``PATTERN_SHARE`` of the triangles (by count)
    map to UV near conformally (singular values within 25 % of each other) at one scale (within 25 % of
    the median), as flattened pattern pieces are; texture atlases stretch and scale their islands."""
    if uvs is None or tri_uvs is None or np.any(tri_uvs < 0):
        return False
    p = pos[tris]
    q = uvs[tri_uvs]
    e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    u1, u2 = q[:, 1] - q[:, 0], q[:, 2] - q[:, 0]
    # 3-D edges in the triangle's own plane
    l1 = np.linalg.norm(e1, axis=1)
    ok = l1 > 0
    t = e1 / np.where(ok, l1, 1.0)[:, None]
    nrm = np.cross(e1, e2)
    b = np.cross(nrm, t)
    b /= np.maximum(np.linalg.norm(b, axis=1), 1e-300)[:, None]
    P = np.stack([np.stack([l1, np.zeros_like(l1)], 1), np.stack([np.einsum("ij,ij->i", e2, t),
                                                                 np.einsum("ij,ij->i", e2, b)], 1)], 2)
    U = np.stack([u1, u2], 2)
    det = P[:, 0, 0] * P[:, 1, 1] - P[:, 0, 1] * P[:, 1, 0]
    ok &= np.abs(det) > 0
    if not np.any(ok):
        return False
    J = U[ok] @ np.linalg.inv(P[ok])
    sv = np.linalg.svd(J, compute_uv=False)
    if np.any(sv[:, 1] <= 0):
        return False
    conformal = sv[:, 0] / sv[:, 1] <= 1.25
    scale = np.sqrt(sv[:, 0] * sv[:, 1])
    same = np.abs(scale / np.median(scale) - 1.0) <= 0.25
    return bool(np.mean(conformal & same) >= PATTERN_SHARE)


def build_hinges(face_verts, face_offsets, rest_pos, rigidity, uvs=None, face_uvs=None, damping=0.0):
    """The hinges of a polygon mesh (module docstring).

    Parameters
    ----------
    face_verts : (k,) int64;  face_offsets : (m + 1,) int64
    rest_pos : (n, 3) float64, m
    rigidity : float or (2,) float, N m
        Bending rigidity, or (warp, weft).
    uvs : (t, 2) float64 or None;  face_uvs : (k,) int64 or None
        The garment's texture coordinates per face corner (``vfit_engine.io.meshdata.MeshData``).
    damping : float, s
        Hinge damping ``kd = damping k``.

    Returns
    -------
    Hinges
    """
    fv = np.asarray(face_verts, dtype=np.int64)
    fo = np.asarray(face_offsets, dtype=np.int64)
    pos = np.asarray(rest_pos, dtype=np.float64)
    n = pos.shape[0]
    b_warp, b_weft = np.broadcast_to(np.asarray(rigidity, dtype=np.float64), (2,))
    tri_sets = _triangulations(fv, fo)
    tri_uvs = None
    anisotropic = False
    if uvs is not None and face_uvs is not None:
        uvs = np.asarray(uvs, dtype=np.float64)
        tri_uvs = [np.asarray(face_uvs, dtype=np.int64)[t] for t in _triangulations(np.arange(fv.size), fo)]
        anisotropic = uv_is_pattern(tri_sets[0], tri_uvs[0], uvs, pos)
    parts = [_hinges_of(t, n) for t in tri_sets]
    idx = np.concatenate(parts)
    w = np.full(idx.shape[0], 1.0 / len(parts))
    x0, x1, x2, x3 = (pos[idx[:, m]] for m in range(4))
    e = x1 - x0
    a0 = 0.5 * np.linalg.norm(np.cross(e, x2 - x0), axis=1)
    a1 = 0.5 * np.linalg.norm(np.cross(x3 - x0, e), axis=1)
    le2 = np.einsum("ij,ij->i", e, e)
    longest = np.maximum.reduce([le2, np.sum((x2 - x0) ** 2, 1), np.sum((x2 - x1) ** 2, 1),
                                 np.sum((x3 - x0) ** 2, 1), np.sum((x3 - x1) ** 2, 1)])
    keep = (np.minimum(a0, a1) > MIN_ASPECT * longest) & (le2 > 0)
    idx, w, a0, a1, le2 = idx[keep], w[keep], a0[keep], a1[keep], le2[keep]
    if anisotropic:
        b = _directional_rigidity(idx, tri_sets, tri_uvs, uvs, b_warp, b_weft)
    else:
        b = np.full(idx.shape[0], 0.5 * (b_warp + b_weft))
    k = w * b * le2 / (a0 + a1)
    rest = hinge_angles(idx, pos)
    return Hinges(np.ascontiguousarray(idx), np.ascontiguousarray(k), np.ascontiguousarray(float(damping) * k),
                  np.ascontiguousarray(rest), anisotropic)


def _directional_rigidity(idx, tri_sets, tri_uvs, uvs, b_warp, b_weft):
    """(h,) N m: each hinge's rigidity from its edge's direction in the UV layout (module docstring).

    An edge's UVs are taken from a triangle holding it (a vertex has several UVs at a seam; within one
    triangle they belong together)."""
    n = int(max(t.max() for t in tri_sets)) + 1
    tris, tuv = np.concatenate(tri_sets), np.concatenate(tri_uvs)
    a, b = tris.ravel(), np.roll(tris, -1, axis=1).ravel()
    ua, ub = tuv.ravel(), np.roll(tuv, -1, axis=1).ravel()
    keys = np.r_[a * n + b, b * n + a]
    ends = np.r_[np.stack([ua, ub], 1), np.stack([ub, ua], 1)]
    order = np.argsort(keys, kind="stable")
    keys, ends = keys[order], ends[order]
    at = np.searchsorted(keys, idx[:, 0] * n + idx[:, 1])
    du = uvs[ends[at, 1]] - uvs[ends[at, 0]]
    c2 = du[:, 0] ** 2 / np.maximum(np.sum(du * du, 1), 1e-300)
    return b_warp * c2 + b_weft * (1.0 - c2)


def bending_energy(hinges, pos):
    """Bending energy at ``pos`` (n, 3), J: ``sum k (theta - theta0)^2 / 2``."""
    d = hinge_angles(hinges.indices, np.asarray(pos, dtype=np.float64)) - hinges.rest_angle
    d = (d + math.pi) % (2.0 * math.pi) - math.pi
    return float(0.5 * np.sum(hinges.k * d * d))
