"""The body thickened at its small convex features (vfit_engine.collide.sag) and the contacts that keep it."""
import numpy as np
import pytest
import trimesh

from vfit_engine.collide.body_mesh import MeshCollider
from vfit_engine.collide.sag import SAG_CAP, SAG_TOLERANCE, convex_sag


def test_sphere_rise_is_the_cap_height_of_the_farthest_neighbour():
    """On a sphere of radius R a neighbour at chord c lies c^2 / (2 R) below a vertex's tangent plane, so the
    rise is that of the farthest neighbour within r: between (r - edge)^2 / (2R) and r^2 / (2R)."""
    radius, r, allowance = 0.02, 0.006, 0.0002
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=radius)
    edge = float(sphere.edges_unique_length.max())
    sag = convex_sag(sphere.vertices, sphere.faces, r, allowance)
    hi = r * r / (2 * radius) - allowance
    lo = (r - edge) ** 2 / (2 * radius) - allowance
    assert 0.0 < lo and np.all(sag >= lo) and np.all(sag <= hi + 1e-12)


def test_flat_and_concave_surfaces_get_nothing():
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=0.02)
    inside_out = sphere.faces[:, ::-1]  # the inside of a ball: concave everywhere
    assert not np.any(convex_sag(sphere.vertices, inside_out, 0.006, 0.0))
    x, z = np.meshgrid(np.linspace(0, 0.1, 21), np.linspace(0, 0.1, 21))
    flat = np.stack([x.ravel(), np.zeros(x.size), z.ravel()], axis=1)
    faces = []
    for i in range(20):
        for j in range(20):
            a = i * 21 + j
            faces += [[a, a + 21, a + 1], [a + 1, a + 21, a + 22]]
    assert not np.any(convex_sag(flat, np.array(faces), 0.012, 0.0))


def test_another_sheet_within_reach_is_not_under_the_vertex():
    """A 4 mm slab: the vertices of its top face have the bottom face's within 6 mm, 4 mm below them, but
    facing the other way; they are not what the cloth rests on (the top is flat: no sag)."""
    slab = trimesh.creation.box(extents=(0.1, 0.004, 0.1)).subdivide_to_size(0.004)
    slab.merge_vertices()
    v = np.asarray(slab.vertices)
    sag = convex_sag(v, np.asarray(slab.faces), 0.006, 0.0)
    top = (v[:, 1] > 0.0019) & (np.abs(v[:, 0]) < 0.04) & (np.abs(v[:, 2]) < 0.04)
    assert top.sum() > 50 and not np.any(sag[top])
    assert sag.max() > 0.001  # its corners stand out in every direction, and are found


def test_a_ridge_gets_nothing_and_a_fingertip_is_capped():
    """The drape's lattice (15 mm: r = 8.7 mm; allowance 2 mm). Along an 8 mm-radius cylinder (a finger) the
    cloth rests on the ridge itself: across it the rise is 4.7 mm, but 30 degrees off its axis (the edge of
    the sector along it) only 1.2 mm: no sag. An 8 mm ball (a fingertip) falls away by 4.7 mm in every
    direction: more than the cap, which it gets."""
    r, allowance = 0.015 / np.sqrt(3.0), 0.002
    finger = trimesh.creation.cylinder(radius=0.008, height=0.08, sections=48).subdivide_to_size(0.003)
    v = np.asarray(finger.vertices)
    side = np.abs(v[:, 2]) < 0.02  # away from the ends
    assert side.sum() > 50 and not np.any(convex_sag(v, np.asarray(finger.faces), r, allowance)[side])
    tip = trimesh.creation.icosphere(subdivisions=3, radius=0.008)
    np.testing.assert_allclose(convex_sag(tip.vertices, tip.faces, r, allowance), SAG_CAP)


def test_make_contacts_moves_the_half_space_out_by_the_sag():
    """The contact generation kernel against its definition: a point is in contact when its distance less the
    body's extra thickness e is within skin + reach; its half-space is the tangent plane moved out by e."""
    from vfit_engine.kernels.contact_make import make_contacts

    sphere = trimesh.creation.icosphere(subdivisions=3, radius=0.1)
    body = MeshCollider(sphere.vertices, sphere.faces)
    rng = np.random.default_rng(5)
    n = 200
    dirs = rng.normal(size=(n, 3))
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    x = np.ascontiguousarray(dirs * (0.1 + rng.uniform(-0.002, 0.012, n))[:, None])
    e, skin, reach, max_push = 0.0015, 0.001, 0.002, 0.0005
    sag = np.full(sphere.vertices.shape[0], e)
    v = np.repeat(np.arange(n)[:, None], 3, axis=1)
    b = np.tile([1.0, 0.0, 0.0], (n, 1))
    st = dict(p_last=np.zeros((n, 3)), d_last=np.full(n, -np.inf), c_n=np.zeros((n, 3)), c_nq=np.zeros(n),
              c_h=np.zeros(n), c_list=np.zeros(n, np.int64), c_n2=np.zeros((n, 3)), c_nq2=np.full(n, np.nan),
              c_h2=np.zeros(n))
    n_c, queries = make_contacts(x, np.ones(n), v, b, np.full(n, skin), np.zeros((0, 4)), body.grid, True, reach,
                                 max_push, 0.0, st["p_last"], st["d_last"], st["c_n"], st["c_nq"], st["c_h"],
                                 st["c_list"], st["c_n2"], st["c_nq2"], st["c_h2"], 0, n, np.zeros((0, 3)),
                                 np.zeros((0, 3)), np.zeros((0, 3)), sag, e, -np.inf)
    d, q, normal, _ = body.query(x, max_out=1.0, max_in=1.0)
    band = skin + reach
    touching = d - e < band
    assert queries == n and n_c == touching.sum() and 0 < n_c < n
    listed = st["c_list"][:n_c]
    np.testing.assert_array_equal(np.sort(listed), np.flatnonzero(touching))
    plane = np.einsum("pd,pd->p", normal, q) + e
    np.testing.assert_allclose(st["c_nq"][listed], plane[listed], atol=1e-12)
    np.testing.assert_allclose(st["c_h"][listed], plane[listed] + np.minimum(skin, d - e + max_push)[listed],
                               atol=1e-12)
    clear = ~touching
    # a clear point's bound: its distance less the thickness, never below the band
    np.testing.assert_allclose(st["d_last"][clear], np.maximum(band, np.minimum(d - e, band + 4 * reach))[clear],
                               atol=1e-12)


def _bumped_sphere(radius=0.06, height=0.004, width=0.004):
    """A ball with a nipple-like bump on top: the radius grows by ``height`` exp(-s^2 / (2 width^2)) at arc
    length s from the top."""
    ball = trimesh.creation.icosphere(subdivisions=5, radius=1.0)
    v = np.asarray(ball.vertices)
    s = radius * np.arccos(np.clip(v[:, 1], -1, 1))
    return v * (radius + height * np.exp(-s * s / (2 * width * width)))[:, None], np.asarray(ball.faces)


@pytest.mark.parametrize("sag", [True, False])
def test_taut_cloth_over_a_small_bump_is_held_off_its_tip(sag):
    """A 6 cm quad pulled down over a 4 mm bump on a ball: its contact points (15 mm apart) straddle the
    bump's tip. With the sag the tip cuts less than the tolerance (0.5 mm); without, 1.8 mm."""
    from vfit_engine.drape.metrics import surface_penetration
    from vfit_engine.sim.springs import grid_polygons
    from vfit_engine.io.meshdata import MeshData
    from vfit_engine.sim.model import Model
    from vfit_engine.sim.contact_points import contact_points
    from vfit_engine.sim.solver_verlet import ContactSettings, SolverVerlet, VerletSettings

    verts, faces = _bumped_sphere()
    body = MeshCollider(verts, faces)
    pos, fv, fo = grid_polygons(2, 2, 0.06, 0.06)
    pos = np.ascontiguousarray(pos - pos.mean(axis=0) + [0.004, 0.066, 0.003])
    model = Model.from_polygons(fv, fo, pos, "cotton")
    solver = SolverVerlet(model, VerletSettings(substeps=8, gravity=(0.0, -30.0, 0.0)), ContactSettings(sag=sag),
                          body=body, points=contact_points(fv, fo, pos, spacing=0.015))
    state = solver.init_state(1 / 480)
    for _ in range(30):
        solver.step_frame(state, 1 / 60)
    depth = surface_penetration(body, state.pos, MeshData(state.pos, fo, fv).triangles())["surface_max_depth_mm"]
    assert np.all(np.isfinite(state.pos))
    # with the sag the cut is within what the thickness leaves by design (SAG_TOLERANCE: 0.46 mm here)
    assert depth < 1000 * SAG_TOLERANCE if sag else depth > 1.5
