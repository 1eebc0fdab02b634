"""Fit maps: per-vertex figures of a draped garment (``OUTDIR/fit.ply``).

Every map is one float per garment vertex, in the garment's vertex order:

``strain``        fraction: the largest yarn-edge strain at the vertex against the garment as given
                  (the polygons' own edges; :func:`vfit_engine.drape.metrics.vertex_strain`).
``shear_deg``     degrees: the largest change of a polygon corner angle at the vertex.
``ease_mm``       mm: signed distance from the skin along the body's normal (the closest body point's
                  outward normal; negative: pressed into the body). Beyond ``EASE_REACH`` it is capped.
``pressure_kpa``  kPa: contact pressure of the settled cloth on the body (below); 0 off the body.
``contact``       1 where the cloth rests on the body (``ease_mm`` <= ``CONTACT_MM``), else 0.

Pressure. A stretched membrane presses on what it is wrapped round by Laplace's law, p = T1 k1 + T2 k2
(tensions T in N/m, curvatures k in 1/m): a tube of radius r under hoop tension T presses p = T / r.
Discretely, each yarn edge e of rest length l0 carries the force of a strip of the fabric,

    F_e = K max(eps_e, 0) w_e u_e,     w_e = A_e / l0_e,

along its unit direction u_e, with K the fabric's ``stretch_stiffness`` (N/m per unit strain), eps_e its
strain against the garment as given and A_e its share of the rest area (the sum of 2 A_f / n_f over its
polygons, as the solver's springs use: a strip of width w_e). Compressed edges carry nothing (cloth
buckles). A vertex in contact takes the load that pushes it into the body -- the sum of its edges' pulls
and its weight, against the body's outward normal n -- over its share of the draped area a_i:

    p_i = max(0, -n . (sum_e F_e + m_i g)) / a_i.

For a quad tube of N sides under uniform hoop strain this gives 2 T sin(pi/N) h / (2 pi r h / N) = T / r
to within (pi/N)^2 / 6; the tests hold it to 10 %. The tension is the fabric's measured stiffness times
the settled strain, not the solver's constraint forces (its strain limits are not a material law). For
scale, medical compression garments press 1.3-4 kPa.
"""
from __future__ import annotations

import numpy as np

from vfit_engine.drape.metrics import corner_angles, vertex_strain
from vfit_engine.sim.springs import polygon_areas

#: Distance within which a vertex counts as resting on the body, mm (the contact skin is 2-3 mm).
CONTACT_MM = 5.0
#: ``ease_mm`` is exact up to this distance from the body, m; farther cloth reads this value.
EASE_REACH = 0.5
#: The maps in ``fit.ply``'s vertex properties, in order.
MAP_NAMES = ("strain", "shear_deg", "ease_mm", "pressure_kpa", "contact")
#: Units of the maps (``report.json`` and the PLY header's comments say them).
MAP_UNITS = {"strain": "fraction", "shear_deg": "deg", "ease_mm": "mm", "pressure_kpa": "kPa", "contact": "0/1"}


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


def contact_pressure(mesh, pos, stiffness, areal_density, normals, contact, gravity=(0.0, -9.81, 0.0)):
    """Contact pressure (module docstring) of the garment ``mesh`` (as given) at ``pos``.

    Parameters
    ----------
    mesh : MeshData
        The garment as given (rest lengths and areas), metres.
    pos : (n, 3) float64, m
    stiffness : float, N/m
        The fabric's stretch stiffness (tension per unit width per unit strain).
    areal_density : float, kg/m^2
    normals : (n, 3) float64
        The body's outward unit normal at each vertex's closest point.
    contact : (n,) bool
        Vertices resting on the body; the others get 0.
    gravity : (3,) m/s^2

    Returns
    -------
    (n,) float64, kPa
    """
    pos = np.asarray(pos, dtype=np.float64)
    edges = mesh.edges()
    rest = mesh.verts
    l0 = np.linalg.norm(rest[edges[:, 1]] - rest[edges[:, 0]], axis=1)
    d = pos[edges[:, 1]] - pos[edges[:, 0]]
    length = np.linalg.norm(d, axis=1)
    ok = (l0 > 0) & (length > 0)
    width = np.where(ok, edge_area_shares(mesh) / np.where(ok, l0, 1.0), 0.0)
    pull = stiffness * np.maximum(length / np.where(ok, l0, 1.0) - 1.0, 0.0) * width  # N
    f_edge = np.where(ok, pull / np.where(ok, length, 1.0), 0.0)[:, None] * d  # on vertex 0, towards 1
    force = np.zeros_like(pos)
    np.add.at(force, edges[:, 0], f_edge)
    np.add.at(force, edges[:, 1], -f_edge)
    rest_area = vertex_areas(mesh, rest)
    force += areal_density * rest_area[:, None] * np.asarray(gravity, dtype=np.float64)
    load = np.maximum(-np.einsum("ij,ij->i", force, normals), 0.0)
    area = vertex_areas(mesh, pos)
    p = np.where(contact & (area > 0), load / np.where(area > 0, area, 1.0), 0.0)
    return p / 1000.0


def vertex_shear_deg(mesh, pos):
    """(n,) float64, deg: the largest change of a polygon corner angle at each vertex."""
    d = np.degrees(np.abs(corner_angles(pos, mesh.face_verts, mesh.face_offsets)
                          - corner_angles(mesh.verts, mesh.face_verts, mesh.face_offsets)))
    out = np.zeros(mesh.n_verts)
    np.maximum.at(out, mesh.face_verts, d)
    return out


def fit_maps(setup, pos):
    """All the maps (module docstring) of a drape of ``setup`` (:class:`vfit_engine.drape.DrapeSetup`)
    ending at ``pos`` (n, 3) m: dict name -> (n,) float64, in :data:`MAP_NAMES` order."""
    pos = np.ascontiguousarray(pos, dtype=np.float64)
    mesh = setup.garment.mesh
    d, _, normal, tri = setup.collider.query(pos, max_out=EASE_REACH, max_in=EASE_REACH)
    d = np.clip(d, -EASE_REACH, EASE_REACH)  # +-inf beyond the exact range
    ease = 1000.0 * d
    contact = ease <= CONTACT_MM
    mat = setup.material
    pressure = contact_pressure(mesh, pos, mat.stretch_stiffness, mat.areal_density, normal, contact & (tri >= 0))
    return dict(strain=vertex_strain(mesh, pos), shear_deg=vertex_shear_deg(mesh, pos), ease_mm=ease,
                pressure_kpa=pressure, contact=contact.astype(np.float64))
