"""Contact pressure of cloth on the body by Laplace's law (the ``pressure_kpa`` fit map).

A stretched membrane presses on what it is wrapped round with p = T1 k1 + T2 k2 (tensions T in N/m,
curvatures k in 1/m along the principal directions); a tube under hoop tension T round a limb of radius r
presses p = T / r, a sphere under isotropic tension 2 T / r. In tensor form p = sigma : S, sigma the
cloth's membrane tension (N/m) and S the shape operator of the surface it lies on (1/m). Both halves are
taken where they are robust:

*Tension* -- from the fabric's measured stretch stiffness K (``Material.stretch_stiffness``, N/m per
unit strain) and each yarn edge's strain eps against the garment as given, minus the band the solver
leaves free (``VerletSettings.slack``: crimp straightening, no force), tension only (cloth buckles
rather than compresses): t_e = K max(eps_e - slack, 0). Each edge is a strip of the fabric of rest width
w_e = A_e / l0_e (A_e its share of its polygons' rest area, as the solver's springs take it), and a
vertex's tension tensor is the average over the strips that meet there,

    sigma_i = sum_e 1/2 t_e w_e l_e u_e u_e^T / a_i        (u_e the draped edge's direction, l_e its
                                                             length, a_i the vertex's draped area, never
                                                             taken below its rest area),

which is t u u^T on a grid stretched along u, on quads and on triangles alike: the force per draped width
(stretched both ways by e, t / (1 + e) on each axis). The weights A_e / a_i are at most 2 (A_e / a_i of
the rest shape), so a short edge or a collapsed polygon adds no more than its neighbours do.

*Curvature* -- of the body under the cloth, not of the cloth: the cloth's own curvature is noisy at the
scale of its edges (a crease, a fold one vertex wide), and the body's is what a tensioned cloth in
contact is bent to. The body's shape operator per triangle is the gradient of its interpolated vertex
normals (exact on a cylinder or a sphere), averaged to the vertices and smoothed over
:data:`CURVATURE_ROUNDS` rings of neighbours (a few centimetres on hm08: the scale of a fabric's bending
length, 1-3 cm, below which cloth under tension bridges the skin's small dips and creases rather than
follows them). At a cloth vertex it is interpolated at the closest body point, its concave directions
dropped (taut cloth bridges a hollow; it presses nothing there) and taken at the cloth's distance d from
the skin (a parallel surface: k / (1 + d k)). Then p = sigma : S+ >= 0.

The cloth's weight (1-4 Pa for 100-400 g/m^2) is left out: below the map's resolution.
"""
from __future__ import annotations

import numpy as np

from vfit_engine.geometry import closest_point_barycentric, vertex_normals
from vfit_engine.sim.springs import polygon_areas

#: Smoothing rounds of the body's shape operator (each averages a vertex with its one ring: hm08's edges are
#: ~1 cm on the torso); see the module docstring.
CURVATURE_ROUNDS = 3


def edge_area_shares(mesh):
    """(E,) float64, m^2: each edge's share of the rest area, sum of 2 A_f / n_f over its polygons
    (``mesh.edges()`` order): a square grid's edge of side h gets h^2, a strip h wide."""
    edges = mesh.edges()
    fo, fv = mesh.face_offsets, mesh.face_verts
    sizes = np.diff(fo)
    area = polygon_areas(fv, fo, mesh.verts)
    face = np.repeat(np.arange(sizes.size), sizes)
    nxt = fv[fo[face] + (np.arange(fv.size) - fo[face] + 1) % sizes[face]]
    a, b = np.minimum(fv, nxt), np.maximum(fv, nxt)
    keep = a != b  # a repeated corner is no edge (mesh.edges() drops it too)
    a, b, face = a[keep], b[keep], face[keep]
    n = mesh.n_verts
    key = edges[:, 0].astype(np.int64) * n + edges[:, 1]
    order = np.argsort(key)
    idx = order[np.searchsorted(key[order], a.astype(np.int64) * n + b)]
    return np.bincount(idx, weights=2.0 * area[face] / sizes[face], minlength=edges.shape[0])


def vertex_areas(mesh, pos):
    """(n,) float64, m^2: each vertex's share of the polygons' area at ``pos`` (A_f / n_f per corner)."""
    sizes = mesh.face_sizes()
    area = polygon_areas(mesh.face_verts, mesh.face_offsets, pos)
    return np.bincount(mesh.face_verts, weights=np.repeat(area / sizes, sizes), minlength=mesh.n_verts)


def membrane_tension(mesh, pos, stiffness, slack):
    """(n, 3, 3) float64, N/m: each vertex's membrane tension tensor sigma_i (module docstring).

    Parameters
    ----------
    mesh : MeshData
        The garment as given (rest lengths and areas), metres.
    pos : (n, 3) float64, m
    stiffness : float, N/m
        The fabric's stretch stiffness (tension per unit width per unit strain).
    slack : float
        The strain the solver leaves free (no tension up to it).
    """
    pos = np.asarray(pos, dtype=np.float64)
    edges = mesh.edges()
    rest = mesh.verts
    l0 = np.linalg.norm(rest[edges[:, 1]] - rest[edges[:, 0]], axis=1)
    d = pos[edges[:, 1]] - pos[edges[:, 0]]
    length = np.linalg.norm(d, axis=1)
    ok = (l0 > 0) & (length > 0)
    l0s, ls = np.where(ok, l0, 1.0), np.where(ok, length, 1.0)
    tension = stiffness * np.maximum(length / l0s - 1.0 - slack, 0.0)  # N/m
    # 1/2 t w l u u^T = 1/2 t (A / l0) d d^T / l
    coef = np.where(ok, 0.5 * tension * edge_area_shares(mesh) / (l0s * ls), 0.0)
    outer = (coef[:, None, None] * d[:, :, None] * d[:, None, :]).reshape(-1, 9)
    both = np.concatenate([edges[:, 0], edges[:, 1]])
    sigma = np.stack([np.bincount(both, weights=np.tile(outer[:, j], 2), minlength=mesh.n_verts)
                      for j in range(9)], axis=1).reshape(-1, 3, 3)
    # never less than the rest area: a crumpled or collapsed vertex (a fold, a sliver) does not concentrate
    # the tension of its edges (cloth buckles rather than narrows)
    area = np.maximum(vertex_areas(mesh, pos), vertex_areas(mesh, rest))
    return sigma / np.where(area > 0, area, np.inf)[:, None, None]


def body_shape_operator(verts, tris, normals, rounds=CURVATURE_ROUNDS):
    """(V, 3, 3) float64, 1/m: the body's shape operator at each vertex (module docstring), symmetric, in
    world coordinates; u . S u is the normal curvature along the unit tangent u (> 0 convex).

    Parameters
    ----------
    verts : (V, 3) float64, m
    tris : (T, 3) int
    normals : (V, 3) float64
        Unit outward vertex normals.
    rounds : int
        Smoothing rounds over the vertices' rings.
    """
    p = [verts[tris[:, k]] for k in range(3)]
    cross = np.cross(p[1] - p[0], p[2] - p[0])
    double_area = np.linalg.norm(cross, axis=1)
    good = double_area > 0
    nf = cross / np.where(good, double_area, 1.0)[:, None]
    g = np.zeros((tris.shape[0], 3, 3))
    for k in range(3):  # grad lambda_k = n x (opposite edge) / 2A; G = sum n_k grad lambda_k^T
        grad = np.cross(nf, p[(k + 2) % 3] - p[(k + 1) % 3]) / np.where(good, double_area, 1.0)[:, None]
        g += normals[tris[:, k]][:, :, None] * grad[:, None, :]
    s = 0.5 * (g + g.transpose(0, 2, 1))
    tangent = np.eye(3) - nf[:, :, None] * nf[:, None, :]
    s = np.where(good[:, None, None], tangent @ s @ tangent, 0.0)
    weight = np.where(good, double_area, 0.0)
    n = len(verts)
    corner_w = np.bincount(tris.ravel(), weights=np.repeat(weight, 3), minlength=n)
    corner_w = np.where(corner_w > 0, corner_w, 1.0)
    # the least rotations from each triangle's plane to its corners' (fixed over the rounds)
    turn = [_rotation(nf, normals[tris[:, k]]) for k in range(3)]
    out = _to_vertices(tris, s, turn, weight, corner_w)
    for _ in range(int(rounds)):
        per_tri = sum(r.transpose(0, 2, 1) @ out[tris[:, k]] @ r for k, r in enumerate(turn)) / 3.0
        out = _to_vertices(tris, per_tri, turn, weight, corner_w)
    return out


def _rotation(n_from, n_to):
    """(m, 3, 3) least rotations taking unit ``n_from`` to ``n_to`` (Rodrigues). Tensors of differently tilted
    planes are turned into one plane before they are averaged: without it, they would shed their curvature
    into the normal direction (3 % on a cylinder of 48 sides after 3 rounds)."""
    v = np.cross(n_from, n_to)
    c = np.einsum("ij,ij->i", n_from, n_to)
    vx = np.zeros((len(v), 3, 3))
    vx[:, 0, 1], vx[:, 0, 2], vx[:, 1, 2] = -v[:, 2], v[:, 1], -v[:, 0]
    vx -= vx.transpose(0, 2, 1)
    return np.eye(3) + vx + (vx @ vx) / np.maximum(1.0 + c, 1e-6)[:, None, None]


def _to_vertices(tris, per_tri, turn, weight, corner_w):
    """Area-weighted average at each vertex of per-triangle (T, 3, 3) tensors, each turned by ``turn[k]`` into
    the plane of its corner k."""
    n = len(corner_w)
    out = np.zeros((n, 9))
    for k, r in enumerate(turn):
        moved = (r @ per_tri @ r.transpose(0, 2, 1) * weight[:, None, None]).reshape(-1, 9)
        for j in range(9):
            out[:, j] += np.bincount(tris[:, k], weights=moved[:, j], minlength=n)
    return (out / corner_w[:, None]).reshape(n, 3, 3)


def contact_curvature(shape, tris, body_verts, body_normals, tri, closest, distance):
    """(n, 3, 3) float64, 1/m: the body's convex curvature under each cloth vertex (module docstring):
    ``shape`` (:func:`body_shape_operator`) interpolated at the closest body point (``closest``, on triangle
    ``tri`` of ``tris``; -1: none, zero curvature), projected on the tangent plane of the interpolated
    ``body_normals``, its concave directions dropped and taken at ``distance`` (m) off the skin."""
    n = len(tri)
    out = np.zeros((n, 3, 3))
    hit = np.flatnonzero(tri >= 0)
    if hit.size == 0:
        return out
    t = tris[tri[hit]]
    w = closest_point_barycentric(closest[hit], body_verts[t[:, 0]], body_verts[t[:, 1]], body_verts[t[:, 2]])
    s = np.einsum("ik,iklm->ilm", w, shape[t])
    nrm = np.einsum("ik,ikl->il", w, body_normals[t])
    nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-12)
    tangent = np.eye(3) - nrm[:, :, None] * nrm[:, None, :]
    s = tangent @ s @ tangent
    k, vec = np.linalg.eigh(0.5 * (s + s.transpose(0, 2, 1)))
    d = np.clip(distance[hit], 0.0, None)[:, None]
    k = np.maximum(k, 0.0) / (1.0 + d * np.maximum(k, 0.0))  # convex part, on the cloth's parallel surface
    out[hit] = np.einsum("ilk,ik,imk->ilm", vec, k, vec)
    return out


def contact_pressure(mesh, pos, stiffness, slack, curvature, contact):
    """(n,) float64, kPa: p = sigma : S+ (module docstring) at the vertices in ``contact`` ((n,) bool), 0
    elsewhere; ``curvature`` (n, 3, 3) 1/m from :func:`contact_curvature`; the other arguments as
    :func:`membrane_tension` takes them."""
    sigma = membrane_tension(mesh, pos, stiffness, slack)
    p = np.einsum("ilm,ilm->i", sigma, curvature)
    return np.where(contact, np.maximum(p, 0.0), 0.0) / 1000.0


def _near(tris, seed, rings):
    """(T,) bool: the triangles within ``rings`` rings of the triangles ``seed`` (the shape operator at the
    contacts depends on no others: each smoothing round reaches one ring farther)."""
    near = np.zeros(len(tris), dtype=bool)
    near[seed] = True
    marked = np.zeros(int(tris.max()) + 1 if tris.size else 0, dtype=bool)
    for _ in range(int(rings)):
        marked[tris[near].ravel()] = True
        near = marked[tris].any(axis=1)
    return near


def collider_pressure(mesh, pos, material, collider, query, contact, slack):
    """Contact pressure, kPa, of ``mesh`` at ``pos`` on the body of ``collider`` (a still or moving body
    collider: its ``verts`` and ``tris``); ``query`` its ``(d, closest, normal, tri)`` at ``pos``; ``contact``
    (n,) bool; ``material`` the fabric; ``slack`` the strain the solver leaves free."""
    d, closest, _, tri = query
    tris = collider.tris
    normals = vertex_normals(collider.verts, tris, outward=True)
    shape = body_shape_operator(collider.verts, tris[_near(tris, tri[contact & (tri >= 0)], CURVATURE_ROUNDS + 2)],
                                normals)
    curvature = contact_curvature(shape, collider.tris, collider.verts, normals, np.where(contact, tri, -1), closest,
                                  np.where(np.isfinite(d), d, 0.0))
    return contact_pressure(mesh, pos, material.stretch_stiffness, slack, curvature, contact)
