"""Contact pressure by Laplace's law (vfit_engine.fit.pressure) against analytic cases: a tube stretched round a
cylinder presses K e / r, a stretched sphere 2 T / r, slack cloth nothing, and a crease does not spike it."""
import numpy as np
import pytest

from test_fit import tube
from vfit_engine.collide.body_mesh import MeshCollider
from vfit_engine.fit.pressure import body_shape_operator, collider_pressure, contact_curvature, contact_pressure
from vfit_engine.io.meshdata import mesh_from_faces
from vfit_engine.sim.materials import get_material

SLACK = 0.015


def body_cylinder(radius):
    """A closed body cylinder (48 sides, 2 cm rings) round the Y axis from -0.3 to 0.3 m and its collider."""
    verts, faces = tube(radius, 48, 31, 0.6, y0=-0.3, cap=True)
    body = mesh_from_faces(verts, faces)
    return MeshCollider(body.verts, body.triangles())


def uv_sphere(radius, rings, sides):
    """A latitude-longitude quad sphere without its poles (vertices ring by ring from the south) and its faces."""
    lat = np.linspace(-0.5 * np.pi, 0.5 * np.pi, rings + 2)[1:-1]
    lon = 2.0 * np.pi * np.arange(sides) / sides
    verts = np.array([[radius * np.cos(b) * np.sin(a), radius * np.sin(b), radius * np.cos(b) * np.cos(a)]
                      for b in lat for a in lon])
    faces = [[r * sides + k, r * sides + (k + 1) % sides, (r + 1) * sides + (k + 1) % sides, (r + 1) * sides + k]
             for r in range(rings - 1) for k in range(sides)]
    return verts, faces


def pressure_on(collider, mesh, pos, material, slack=SLACK):
    query = collider.query(pos, max_out=0.5, max_in=0.5)
    contact = (query[0] <= 0.005) & (query[3] >= 0)
    return collider_pressure(mesh, pos, material, collider, query, contact, slack), contact


@pytest.mark.parametrize("radius", [0.04, 0.15])
@pytest.mark.parametrize("sides", [24, 64])
def test_tube_round_a_cylinder_presses_k_e_over_r(radius, sides):
    """A tube of rest circumference 2 pi r / (1 + e) stretched round a cylinder of radius r (2 mm of skin
    between): hoop strain e, tension K (e - slack) (the band the solver leaves free carries none), pressure
    K (e - slack) / r within 5 % (the hoop edges are chords: cos^2(pi / N) low, 1.7 % at 24 sides)."""
    mat = get_material("cotton")
    e, gap = 0.04, 0.002
    r = radius + gap
    rest, faces = tube(r / (1.0 + e), sides, 6, 0.1, y0=-0.05)
    mesh = mesh_from_faces(rest, faces)
    pos = rest * np.array([1.0 + e, 1.0, 1.0 + e])
    p, contact = pressure_on(body_cylinder(radius), mesh, pos, mat)
    assert contact.all()
    expect = mat.stretch_stiffness * (e - SLACK) / r / 1000.0
    assert p == pytest.approx(expect, rel=0.05)


def test_slack_tube_presses_nothing():
    """Strain within the solver's free band, or compressed: no tension, no pressure; so is cloth off the body."""
    mat = get_material("denim")
    col = body_cylinder(0.05)
    for e in (0.0, 0.8 * SLACK, -0.05):
        rest, faces = tube(0.052 / (1.0 + e), 32, 5, 0.1, y0=-0.05)
        mesh = mesh_from_faces(rest, faces)
        p, contact = pressure_on(col, mesh, rest * np.array([1.0 + e, 1.0, 1.0 + e]), mat)
        assert contact.all() and np.all(p == 0.0)
    rest, faces = tube(0.09 / 1.04, 32, 5, 0.1, y0=-0.05)  # stretched but 4 cm off the body
    p, contact = pressure_on(col, mesh_from_faces(rest, faces), rest * np.array([1.04, 1.0, 1.04]), mat)
    assert not contact.any() and np.all(p == 0.0)


def test_axial_stretch_on_a_cylinder_presses_nothing():
    """Tension along a straight generator does not press (its curvature is 0): only the hoop counts."""
    mat = get_material("cotton")
    rest, faces = tube(0.052, 32, 6, 0.1, y0=-0.05)
    p, contact = pressure_on(body_cylinder(0.05), mesh_from_faces(rest, faces), rest * np.array([1, 1.05, 1]), mat)
    assert contact.all()
    assert np.all(p < 1e-3 * mat.stretch_stiffness * (0.05 - SLACK) / 0.052 / 1000.0)


def test_stretched_sphere_presses_2t_over_r():
    """A sphere stretched by e both ways on a body sphere of radius r: p = 2 T / r within 5 % away from the poles
    (where the latitude-longitude mesh's quads turn into slivers), T the force per draped width: K (e - slack)
    per rest width over a width 1 + e wider."""
    mat = get_material("cotton")
    e, r = 0.05, 0.10
    bverts, bfaces = uv_sphere(r - 0.002, 40, 64)
    top, bottom = len(bverts), len(bverts) + 1  # close the poles with fans
    bverts = np.vstack([bverts, [[0, r - 0.002, 0], [0, -(r - 0.002), 0]]])
    n = 64
    bfaces += [[bottom, (k + 1) % n, k] for k in range(n)] + [[top, 39 * n + k, 39 * n + (k + 1) % n] for k in range(n)]
    body = mesh_from_faces(bverts, bfaces)
    col = MeshCollider(body.verts, body.triangles())
    rest, faces = uv_sphere(r / (1.0 + e), 30, 48)
    mesh = mesh_from_faces(rest, faces)
    p, contact = pressure_on(col, mesh, rest * (1.0 + e), mat)
    lat = np.degrees(np.arcsin(rest[:, 1] / np.linalg.norm(rest, axis=1)))
    mid = np.abs(lat) < 45.0
    assert contact[mid].all()
    assert p[mid] == pytest.approx(2.0 * mat.stretch_stiffness * (e - SLACK) / (1.0 + e) / r / 1000.0, rel=0.05)


def test_body_curvature_of_a_cylinder_and_the_concave_part_dropped():
    """The body's shape operator on a cylinder: 1/r round it, 0 along it; at a cloth vertex 2 cm off the skin it
    is the parallel surface's 1/(r + d); a concave (inner) wall gives nothing (taut cloth bridges a hollow)."""
    r = 0.06
    col = body_cylinder(r)
    shape = body_shape_operator(col.verts, col.tris, col.vert_normals)
    ring = np.flatnonzero(np.abs(col.verts[:, 1]) < 0.1)
    hoop = np.stack([np.cos(np.arctan2(col.verts[ring, 0], col.verts[ring, 2])), np.zeros(ring.size),
                     -np.sin(np.arctan2(col.verts[ring, 0], col.verts[ring, 2]))], axis=1)
    k_hoop = np.einsum("ij,ijk,ik->i", hoop, shape[ring], hoop)
    assert k_hoop == pytest.approx(1.0 / r, rel=0.01)
    assert np.all(np.abs(shape[ring, 1, 1]) < 0.01 / r)
    pts = np.array([[0.0, 0.0, r + 0.02]])
    d, closest, _, tri = col.query(pts, max_out=0.5, max_in=0.5)
    s = contact_curvature(shape, col.tris, col.verts, col.vert_normals, tri, closest, d)
    assert s[0, 0, 0] == pytest.approx(1.0 / (r + 0.02), rel=0.01)
    inner = contact_curvature(-shape, col.tris, col.verts, col.vert_normals, tri, closest, d)
    assert np.allclose(inner, 0.0)


def test_a_buckled_hem_does_not_spike_the_pressure():
    """A stretched tube whose last row is buckled along the tube (its edges there at the solver's 30 % compression,
    as at the shared garments' sleeve hems and cuffs) presses as the rest of the tube does, K (e - slack) / r within
    5 %: the old map divided the hoop edges' pull by the buckled row's shrunken draped area (x 1.4 there) and took
    the net force along the cloth's own kinks; here the area is never less than at rest and the curvature is the
    body's."""
    mat = get_material("cotton")
    e, r = 0.06, 0.052
    rest, faces = tube(r / (1.0 + e), 32, 8, 0.14, y0=-0.07)
    mesh = mesh_from_faces(rest, faces)
    pos = rest * np.array([1.0 + e, 1.0, 1.0 + e])
    hem = np.arange(7 * 32, 8 * 32)
    pos[hem, 1] -= 0.3 * 0.02  # the last row 30 % shorter
    p, contact = pressure_on(body_cylinder(0.05), mesh, pos, mat)
    assert contact.all()
    assert p == pytest.approx(mat.stretch_stiffness * (e - SLACK) / r / 1000.0, rel=0.05)


def test_contact_pressure_is_zero_off_contact():
    """Vertices not in contact press nothing, whatever the tension and curvature."""
    rest, faces = tube(0.05, 16, 3, 0.05)
    mesh = mesh_from_faces(rest, faces)
    curvature = np.tile(np.eye(3) * 20.0, (len(rest), 1, 1))
    p = contact_pressure(mesh, rest * 1.1, 2000.0, SLACK, curvature, np.zeros(len(rest), bool))
    assert np.all(p == 0.0)
    assert np.all(contact_pressure(mesh, rest * 1.1, 2000.0, SLACK, curvature, np.ones(len(rest), bool)) > 0)
