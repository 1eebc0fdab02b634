"""MeshCollider: analytic distance tables, brute-force reference, projection, friction, restitution."""
import math
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

sys.path.insert(0, str(Path(__file__).resolve().parent))
import naive_collide  # noqa: E402

from vfit_engine.collide.body_mesh import MeshCollider  # noqa: E402
from vfit_engine.errors import InputError  # noqa: E402

R = 0.1  # sphere radius, m
SKIN = 0.003


@pytest.fixture(scope="module")
def sphere():
    return trimesh.creation.icosphere(subdivisions=3, radius=R)


@pytest.fixture(scope="module")
def sphere_col(sphere):
    return MeshCollider(sphere.vertices, sphere.faces, skin=SKIN, radius=0.5)


@pytest.fixture(scope="module")
def box():
    # half extents 0.5, 0.3, 0.2 m, centred at the origin
    return trimesh.creation.box(extents=(1.0, 0.6, 0.4))


@pytest.fixture(scope="module")
def box_col(box):
    return MeshCollider(box.vertices, box.faces, skin=SKIN, radius=1.0)


def _unit(v):
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v)


# ---------------------------------------------------------------------- distance tables
def test_icosphere_table(sphere, sphere_col):
    # the faceted sphere lies between its inradius (face planes) and R (vertices)
    a, b, c = (sphere.vertices[sphere.faces[:, k]] for k in range(3))
    inradius = np.min(np.abs(np.einsum("ij,ij->i", sphere.face_normals, a)))
    facet = R - inradius
    dirs = [_unit(v) for v in ((1, 0, 0), (0, -1, 0), (0, 0, 1), (1, 1, 1), (-0.3, 0.8, 0.2), (0.5, -0.5, -0.7))]
    for u in dirs:
        for frac, expected in ((0.0, -R), (0.5, -0.5 * R), (1.0, 0.0), (1.5, 0.5 * R)):
            d, q, n = sphere_col.signed_distance((frac * R * u)[None])
            assert abs(d[0] - expected) <= facet + 1e-12, (u, frac, d[0])
            if frac < 1.0:
                assert d[0] < 0
            elif frac > 1.0:
                assert d[0] > 0
            assert abs(np.linalg.norm(n[0]) - 1.0) < 1e-12
            assert np.linalg.norm(frac * R * u - q[0]) == pytest.approx(abs(d[0]), abs=1e-15)


def test_box_exact_table(box_col):
    ax, ay, az = 0.5, 0.3, 0.2
    e = 0.01
    cases = [
        ((ax + e, 0.05, -0.03), e, (1, 0, 0)),  # face
        ((0.1, -ay - 2 * e, 0.02), 2 * e, (0, -1, 0)),  # face
        ((ax - e, 0.05, 0.02), -e, (1, 0, 0)),  # inside, below a face
        ((0.1, 0.0, -az + 0.5 * e), -0.5 * e, (0, 0, -1)),
        ((ax + e, ay + 2 * e, 0.0), math.hypot(e, 2 * e), _unit((1, 2, 0))),  # edge
        ((-ax - e, 0.1, az + e), math.hypot(e, e), _unit((-1, 0, 1))),
        ((ax + e, -ay - e, az + e), math.sqrt(3) * e, _unit((1, -1, 1))),  # corner
        ((ax - e, ay - 2 * e, az - 3 * e), -e, (1, 0, 0)),  # inside near a corner
        ((0.0, 0.0, 0.0), -az, None),  # centre: nearest faces are z = +-0.2 (tie)
    ]
    pts = np.array([c[0] for c in cases])
    d, q, n = box_col.signed_distance(pts)
    for k, (p, expected, normal) in enumerate(cases):
        assert d[k] == pytest.approx(expected, abs=1e-12), (p, d[k])
        if normal is not None:
            np.testing.assert_allclose(n[k], normal, atol=1e-12)
        np.testing.assert_allclose(np.linalg.norm(pts[k] - q[k]), abs(d[k]), atol=1e-12)


def _tetrahedron():
    # face normals 109.5 degrees apart: near an edge or a vertex a single face's normal gives the wrong sign
    v = 0.1 * np.array([[1.0, 1.0, 1.0], [1.0, -1.0, -1.0], [-1.0, 1.0, -1.0], [-1.0, -1.0, 1.0]])
    return trimesh.Trimesh(v, [[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]], process=False)


def test_tetrahedron_sign_needs_pseudo_normals():
    mesh = _tetrahedron()
    assert mesh.is_volume
    rng = np.random.default_rng(4)
    pts = rng.uniform(-0.15, 0.15, size=(3000, 3))
    col = MeshCollider(mesh.vertices, mesh.faces, radius=1.0)
    d, _, _, _ = col.query(pts)
    inside = np.all(np.einsum("ij,kj->ik", pts, mesh.face_normals)
                    < np.einsum("ij,ij->i", mesh.face_normals, mesh.vertices[mesh.faces[:, 0]]), axis=1)
    assert np.array_equal(d < 0, inside)


@pytest.mark.parametrize("kind", ["sphere", "torus", "box", "tetra"])
def test_against_brute_force(kind):
    rng = np.random.default_rng(7)
    if kind == "sphere":
        mesh = trimesh.creation.icosphere(subdivisions=2, radius=0.1)
    elif kind == "torus":  # not convex: concave edges and vertices on the inner ring
        mesh = trimesh.creation.torus(major_radius=0.1, minor_radius=0.035, major_sections=24, minor_sections=12)
    elif kind == "box":
        mesh = trimesh.creation.box(extents=(0.2, 0.12, 0.08))
    else:
        mesh = _tetrahedron()
    lo, hi = mesh.bounds
    pts = rng.uniform(lo - 0.05, hi + 0.05, size=(400, 3))
    # points on or very near the surface as well
    surf, _ = trimesh.sample.sample_surface(mesh, 100, seed=3)
    pts = np.vstack([pts, surf + rng.normal(scale=1e-3, size=surf.shape), mesh.vertices[:20]])
    radius = 0.04
    col = MeshCollider(mesh.vertices, mesh.faces, radius=radius)
    d, q, n, tri = col.query(pts)
    d_ref, q_ref, tri_ref = naive_collide.signed_distance(pts, col.verts, col.tris)
    within = np.abs(d_ref) < radius
    assert within.sum() > 200
    np.testing.assert_allclose(d[within], d_ref[within], rtol=0, atol=1e-12)
    np.testing.assert_allclose(q[within], q_ref[within], rtol=0, atol=1e-12)
    clear = within & (np.abs(d_ref) > 1e-9)
    assert np.all(np.sign(d[clear]) == np.sign(d_ref[clear]))
    # the reported triangle really holds the closest point
    for k in np.flatnonzero(within)[::5]:
        corners = [col.verts[col.tris[tri[k], c]][None] for c in range(3)]
        cq, _ = naive_collide.closest_on_triangles(pts[k], *corners)
        np.testing.assert_allclose(cq[0], q[k], atol=1e-12)
    # beyond the radius: either exact or reported far, with the right sign
    beyond = ~within
    far = np.isinf(d)
    assert np.all(np.sign(d[beyond & far]) == np.sign(d_ref[beyond & far]))
    np.testing.assert_allclose(d[beyond & ~far], d_ref[beyond & ~far], atol=1e-12)
    # unbounded query: exact everywhere
    d_all, _, _, _ = col.query(pts, max_out=np.inf, max_in=np.inf)
    np.testing.assert_allclose(d_all, d_ref, rtol=0, atol=1e-12)


def test_deep_inside_and_far(sphere_col):
    small = MeshCollider(sphere_col.verts, sphere_col.tris, radius=0.02)
    d, q, n = small.signed_distance(np.array([[0.0, 0.0, 0.0], [0.0, 0.5, 0.0], [0.09, 0.0, 0.0]]))
    assert d[0] == -np.inf and d[1] == np.inf and -0.011 < d[2] < -0.009
    assert np.all(np.isnan(q[:2])) and np.all(n[:2] == 0)
    pen = small.penetration(np.array([[0.0, 0.0, 0.0], [0.0, 0.5, 0.0], [0.0, 0.05, 0.0]]))
    assert pen["inside_count"] == 2
    assert pen["inside_mask"].tolist() == [True, False, True]
    assert R - 0.003 < pen["max_depth_m"] <= R  # exact depth even beyond the search radius


def test_on_vertex_and_edge_no_nan(sphere, sphere_col):
    mid = 0.5 * (sphere.vertices[sphere.edges_unique[:, 0]] + sphere.vertices[sphere.edges_unique[:, 1]])
    pts = np.vstack([sphere.vertices, mid, sphere.triangles_center])
    d, q, n = sphere_col.signed_distance(pts)
    assert np.all(np.isfinite(d)) and np.all(np.isfinite(q)) and np.all(np.isfinite(n))
    assert np.max(np.abs(d)) < 1e-15
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-12)
    assert np.all(np.einsum("ij,ij->i", n, pts) > 0)  # outward
    x = pts.copy()
    xp = x.copy()
    sphere_col.project(x, xp, np.ones(len(x)))
    assert np.all(np.isfinite(x))
    dd, _, _ = sphere_col.signed_distance(x)
    np.testing.assert_allclose(dd, SKIN, atol=1e-9)


def test_degenerate_triangle_is_finite():
    mesh = trimesh.creation.icosphere(subdivisions=1, radius=0.1)
    v = np.vstack([mesh.vertices, [[0.0, 0.2, 0.0], [0.0, 0.2, 0.0]]])
    t = np.vstack([mesh.faces, [[0, len(v) - 2, len(v) - 1]]])  # zero-area sliver
    col = MeshCollider(v, t, radius=0.5)
    d, q, n = col.signed_distance(np.random.default_rng(1).uniform(-0.25, 0.25, (200, 3)))
    assert np.all(np.isfinite(d)) and np.all(np.isfinite(q))


# ---------------------------------------------------------------------- projection
def test_project_sphere(sphere_col):
    rng = np.random.default_rng(11)
    u = rng.normal(size=(600, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    r = rng.uniform(0.2 * R, 1.6 * R, 600)
    x = np.ascontiguousarray(u * r[:, None])
    x_prev = x.copy()
    inv_mass = np.ones(len(x))
    inv_mass[::7] = 0.0
    d0, _, _ = sphere_col.signed_distance(x)
    x_before = x.copy()
    count = sphere_col.project(x, x_prev, inv_mass)
    hit = (d0 < SKIN) & (inv_mass > 0)
    assert count == hit.sum() and count > 100
    d1, _, _ = sphere_col.signed_distance(x)
    np.testing.assert_allclose(d1[hit], SKIN, atol=1e-9)
    assert np.array_equal(x[~hit], x_before[~hit])  # far and pinned particles untouched, bit for bit
    assert np.array_equal(x_prev[~hit], x_before[~hit])
    assert np.any((d0 < 0) & (inv_mass == 0))  # a pinned particle inside stays inside
    # started at rest: the push adds no velocity
    np.testing.assert_array_equal(x[hit] - x_prev[hit], 0.0)
    # idempotent: a second call finds nothing to do
    assert sphere_col.project(x, x_prev, inv_mass) == 0


def _slide(collider, vt, vn):
    """One particle over the box's top face (y = 0.3): x_prev above the skin, x below it."""
    y0 = 0.3 + SKIN + 0.001
    x_prev = np.array([[0.0, y0, 0.0]])
    x = np.array([[vt, y0 + vn, 0.0]])
    collider.project(x, x_prev, np.ones(1))
    return x[0], x[0] - x_prev[0]


def test_inelastic_contact_with_friction(box):
    col = MeshCollider(box.vertices, box.faces, skin=SKIN, friction=0.3, restitution=0.0)
    x, v = _slide(col, vt=0.002, vn=-0.004)
    assert x[1] == pytest.approx(0.3 + SKIN, abs=1e-12)
    assert v[1] == pytest.approx(0.0, abs=1e-15)  # normal velocity removed
    # Coulomb: |vt| reduced by friction * normal change = 0.3 * 0.004
    assert v[0] == pytest.approx(0.002 - 0.3 * 0.004, abs=1e-15)
    assert v[2] == 0.0


def test_restitution_and_friction_stop(box):
    col = MeshCollider(box.vertices, box.faces, skin=SKIN, friction=0.3, restitution=0.5)
    x, v = _slide(col, vt=0.002, vn=-0.004)
    assert v[1] == pytest.approx(0.5 * 0.004, abs=1e-15)  # reflected with Cr
    assert v[0] == pytest.approx(0.002 - 0.3 * (1.5 * 0.004), abs=1e-15)
    sticky = MeshCollider(box.vertices, box.faces, skin=SKIN, friction=5.0, restitution=0.0)
    x, v = _slide(sticky, vt=0.002, vn=-0.004)
    assert v[0] == 0.0  # friction stops the slide but never reverses it
    frictionless = MeshCollider(box.vertices, box.faces, skin=SKIN, friction=0.0)
    x, v = _slide(frictionless, vt=0.002, vn=-0.004)
    assert v[0] == pytest.approx(0.002, abs=1e-15)


def test_max_push_ramps_out_without_overshoot(box_col):
    depth = 0.02
    x = np.array([[0.1, 0.3 - depth, 0.05]])
    x_prev = x.copy()
    x = x.copy()
    ys = [x[0, 1]]
    for _ in range(10):
        box_col.project(x, x_prev, np.ones(1), max_push=0.004)
        ys.append(x[0, 1])
        np.testing.assert_array_equal(x - x_prev, 0.0)  # no velocity injected
        # straight out along the closest-point direction
        assert x[0, 0] == pytest.approx(0.1, abs=1e-15) and x[0, 2] == pytest.approx(0.05, abs=1e-15)
    steps = np.diff(ys)
    assert steps[0] == pytest.approx(0.004, abs=1e-15)
    assert np.all(steps >= -1e-15) and np.all(steps <= 0.004 + 1e-15)
    assert ys[-1] == pytest.approx(0.3 + SKIN, abs=1e-12)
    assert max(ys) <= 0.3 + SKIN + 1e-12
    with pytest.raises(InputError):
        box_col.project(x, x_prev, np.ones(1), max_push=0.0)


# ---------------------------------------------------------------------- API
def test_update_follows_moved_mesh(sphere):
    col = MeshCollider(sphere.vertices, sphere.faces, radius=0.2)
    pts = np.random.default_rng(5).uniform(-0.15, 0.15, (300, 3))
    d0, q0, _ = col.signed_distance(pts)
    shift = np.array([0.3, -0.1, 0.05])
    col.update(sphere.vertices + shift)
    d1, q1, _ = col.signed_distance(pts + shift)
    np.testing.assert_allclose(d1, d0, atol=1e-12)
    np.testing.assert_allclose(q1 - shift, q0, atol=1e-12)


def test_refit_matches_rebuild():
    sphere = trimesh.creation.icosphere(subdivisions=2, radius=R)
    col = MeshCollider(sphere.vertices, sphere.faces, radius=0.2, cell=0.025)
    origin, dims = col.origin.copy(), col.dims.copy()
    old_grid = col.grid
    old_sd = old_grid.cell_sd.copy()
    rng = np.random.default_rng(8)
    pts = np.vstack([rng.uniform(-0.2, 0.2, (300, 3)), sphere.vertices[::4] * rng.uniform(0.8, 1.2, (1, 1))])
    # a small deformation keeps the grid box (and loosens the empty cells' bounds); a large
    # translation moves it (and recomputes them)
    bumpy = sphere.vertices * (1.0 + 0.03 * np.sin(7.0 * sphere.vertices[:, :1]))
    moved = bumpy + [0.4, -0.1, 0.05]
    for verts, keeps_box in ((bumpy, True), (moved, False), (moved + 0.002 * np.cos(9.0 * moved), True)):
        col.refit(verts)
        assert np.array_equal(col.origin, origin) == keeps_box and np.array_equal(col.dims, dims) == keeps_box
        origin, dims = col.origin.copy(), col.dims.copy()
        fresh = MeshCollider(verts, sphere.faces, radius=0.2)  # its own cell size
        q_pts = pts + verts.mean(axis=0)
        d, q, n, _ = col.query(q_pts)
        d_ref, q_ref, _, _ = fresh.query(q_pts)
        within = np.abs(d_ref) < 0.2
        assert within.sum() > 250
        np.testing.assert_allclose(d[within], d_ref[within], rtol=0, atol=1e-12)
        np.testing.assert_allclose(q[within], q_ref[within], rtol=0, atol=1e-12)
        assert np.all(np.sign(d[~within]) == np.sign(d_ref[~within]))
        d_naive, _, _ = naive_collide.signed_distance(q_pts[within][::10], col.verts, col.tris)
        np.testing.assert_allclose(d[within][::10], d_naive, rtol=0, atol=1e-12)
        _check_grid(col)
    # the grid taken before the refits is untouched
    assert np.array_equal(old_grid.cell_sd, old_sd)
    assert col.grid is not old_grid
    with pytest.raises(InputError):
        col.refit(sphere.vertices[:-1])


def test_grid_is_a_read_only_body_grid(sphere_col):
    from vfit_engine.kernels.collide_mesh import BodyGrid

    g = sphere_col.grid
    assert isinstance(g, BodyGrid)
    assert g._fields == ("tri_data", "tris", "tri_normals", "tri_edges", "edge_normals", "vert_normals", "origin",
                         "dims", "h", "margin", "cell_start", "cell_tris", "cell_tdist", "cell_sd", "cell_sd_hi")
    assert g.cell_sd_hi is g.cell_sd  # a still body: one array, its centres' exact distances
    for name in ("tri_data", "tris", "tri_normals", "tri_edges", "edge_normals", "vert_normals", "origin", "dims",
                 "cell_start", "cell_tris", "cell_tdist", "cell_sd"):
        assert getattr(g, name).flags.c_contiguous, name
    assert type(g.h) is float and type(g.margin) is float
    with pytest.raises(AttributeError):
        sphere_col.grid = g


def _check_grid(col):
    """The grid against brute force: lists, level floors, centre distances, empty-cell bounds."""
    g = col.grid
    nx, ny, nz = g.dims
    i, j, k = np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij")
    centres = g.origin + (np.stack([i, j, k], axis=-1).reshape(-1, 3) + 0.5) * g.h
    reach = g.margin + 0.5 * math.sqrt(3.0) * g.h
    tris = g.tris  # grid order
    dist = naive_collide.distances_to_triangles(centres, col.verts, tris)
    d_ref, _, _ = naive_collide.signed_distance(centres, col.verts, tris)
    counts = np.diff(g.cell_start)
    for c in range(len(centres)):
        listed = g.cell_tris[g.cell_start[c]:g.cell_start[c + 1]]
        floors = g.cell_tdist[g.cell_start[c]:g.cell_start[c + 1]]
        # every triangle within reach, nothing beyond (but for the kernel's 1e-9 relative slack)
        need, allowed = set(np.flatnonzero(dist[c] <= reach - 1e-12)), set(np.flatnonzero(dist[c] <= reach + 1e-8))
        assert need <= set(listed) <= allowed
        assert np.all(floors <= dist[c, listed]) and np.all(np.diff(floors) >= 0)
        assert np.all(dist[c, listed] - floors < reach / 64 + 1e-12)
    band = counts > 0
    np.testing.assert_allclose(g.cell_sd[band], d_ref[band], rtol=0, atol=1e-12)
    assert np.all(np.sign(g.cell_sd[~band]) == np.sign(d_ref[~band]))
    assert np.all(np.abs(g.cell_sd[~band]) <= np.abs(d_ref[~band]))
    assert np.all(np.abs(g.cell_sd[~band]) >= reach * (1 - 1e-12))


@pytest.mark.parametrize("kind", ["torus", "tetra"])
def test_grid_against_brute_force(kind):
    if kind == "torus":  # concave, and an empty region inside the tube
        mesh = trimesh.creation.torus(major_radius=0.1, minor_radius=0.04, major_sections=12, minor_sections=8)
    else:
        mesh = _tetrahedron()
    col = MeshCollider(mesh.vertices, mesh.faces, cell=0.012)
    _check_grid(col)
    # the empty cells' bound is the exact distance to the nearest listed centre, less half a diagonal
    g = col.grid
    band = np.diff(g.cell_start) > 0
    ndimage = pytest.importorskip("scipy.ndimage")
    edt = ndimage.distance_transform_edt(~band.reshape(tuple(g.dims)), sampling=g.h).ravel()
    half = 0.5 * math.sqrt(3.0) * g.h
    np.testing.assert_allclose(np.abs(g.cell_sd[~band]), np.maximum(g.margin + half, edt[~band] - half),
                               rtol=1e-12, atol=1e-15)


def test_mesh_normals_against_loops():
    from vfit_engine.collide.body_mesh import mesh_normals

    mesh = trimesh.creation.torus(major_radius=0.1, minor_radius=0.035, major_sections=16, minor_sections=9)
    tri_n, tri_e, edge_n, vert_n = mesh_normals(mesh.vertices, mesh.faces)
    fn, en, vn = naive_collide.pseudo_normals(np.asarray(mesh.vertices), np.asarray(mesh.faces))
    np.testing.assert_allclose(tri_n, fn, atol=1e-12)
    np.testing.assert_allclose(vert_n, vn, atol=1e-12)
    for t, face in enumerate(mesh.faces):
        for k in range(3):
            key = tuple(sorted((face[k], face[(k + 1) % 3])))
            np.testing.assert_allclose(edge_n[tri_e[t, k]], en[key], atol=1e-12)
    assert len(edge_n) == len(en)


def test_region_labels_and_distance_transform_against_scipy():
    from vfit_engine.kernels import collide_mesh_empty as E

    ndimage = pytest.importorskip("scipy.ndimage")
    rng = np.random.default_rng(12)
    dims = np.array([13, 9, 11])
    band = (rng.random(int(np.prod(dims))) < 0.35).astype(np.uint8)
    label, parent = np.empty(band.size, np.int32), np.empty(band.size, np.int32)
    n = E._label_regions(dims, band, label, parent)
    roots = np.array([E._root(parent, q) for q in range(n)])
    ref, _ = ndimage.label(band.reshape(tuple(dims)) == 0)
    empty = band == 0
    ours = roots[label[empty]]
    theirs = ref.ravel()[empty]
    # the same partition: a one-to-one map between the two labellings
    pairs = set(zip(ours.tolist(), theirs.tolist()))
    assert len(pairs) == len(set(ours.tolist())) == len(set(theirs.tolist()))
    d2 = np.empty(band.size)
    E._band_distance2(dims, band, d2)
    np.testing.assert_array_equal(d2, np.round(ndimage.distance_transform_edt(empty.reshape(tuple(dims))).ravel() ** 2))


def test_deterministic(sphere_col):
    pts = np.random.default_rng(2).uniform(-0.15, 0.15, (500, 3))
    a = sphere_col.query(pts)
    b = sphere_col.query(pts)
    for u, w in zip(a, b):
        assert u.tobytes() == w.tobytes()


def test_bad_input(sphere, sphere_col):
    x = np.zeros((3, 3))
    with pytest.raises(InputError):
        sphere_col.project(x.astype(np.float32), x.copy(), np.ones(3))
    with pytest.raises(InputError):
        sphere_col.project(x, np.zeros((2, 3)), np.ones(3))
    with pytest.raises(InputError):
        sphere_col.project(x, x.copy(), np.ones(2))
    with pytest.raises(InputError):
        sphere_col.project(np.asfortranarray(np.zeros((3, 3))), x.copy(), np.ones(3))
    with pytest.raises(InputError):
        sphere_col.signed_distance(np.array([[np.nan, 0.0, 0.0]]))
    with pytest.raises(InputError):
        MeshCollider(sphere.vertices, sphere.faces + 10_000)
    with pytest.raises(InputError):
        MeshCollider(sphere.vertices, sphere.faces, skin=-1.0)
