"""SolverVerlet, Model, springs-from-topology and materials."""
import json

import numpy as np
import pytest
import trimesh

from vfit_engine.collide.spheres import SphereCollider
from vfit_engine.errors import InputError
from vfit_engine.garment.springs import (BEND, SHEAR, STRUCTURAL, build_springs, grid_polygons, polygon_areas,
                                         spring_constants, vertex_masses)
from vfit_engine.sim.materials import PRESETS, Material, load_material, resolve_material
from vfit_engine.sim.model import Model
from vfit_engine.sim.solver_verlet import SolverVerlet, VerletSettings


def _tri_polys(faces):
    faces = np.asarray(faces, dtype=np.int64)
    return faces.ravel(), np.arange(0, faces.size + 1, faces.shape[1], dtype=np.int64)


def _counts(fv, fo, pos):
    s = build_springs(fv, fo, pos)
    return s.count_of(STRUCTURAL), s.count_of(SHEAR), s.count_of(BEND)


# -- springs from topology ----------------------------------------------------------

@pytest.mark.parametrize("n", [3, 4, 6])
def test_quad_grid_spring_counts(n):
    pos, fv, fo = grid_polygons(n, n)
    assert _counts(fv, fo, pos) == (2 * n * (n - 1), 2 * (n - 1) ** 2, 2 * n * (n - 2))
    s = build_springs(fv, fo, pos)
    bend = s.indices[s.type == BEND]
    assert set(np.abs(bend[:, 1] - bend[:, 0])) == {2, 2 * n}  # i to i+2 along rows and columns
    assert np.unique(s.indices, axis=0).shape[0] == s.count


def test_triangle_mesh_spring_counts():
    # two triangles: one bend pair (the opposite vertices)
    pos = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    fv, fo = _tri_polys([[0, 1, 2], [0, 2, 3]])
    assert _counts(fv, fo, pos) == (5, 0, 1)
    assert set(map(tuple, build_springs(fv, fo, pos).indices[-1:])) == {(1, 3)}
    # tetrahedron: each opposite pair is an edge already -> no bend springs
    tet = trimesh.creation.box().vertices[[0, 3, 5, 6]]
    fv, fo = _tri_polys([[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]])
    assert _counts(fv, fo, tet) == (6, 0, 0)
    # octahedron: opposite vertices across every edge are antipodes -> 3 bend pairs
    octa = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
    hull = trimesh.convex.convex_hull(octa)
    fv, fo = _tri_polys(hull.faces)
    assert _counts(fv, fo, hull.vertices) == (12, 0, 3)
    ico = trimesh.creation.icosahedron()
    fv, fo = _tri_polys(ico.faces)
    assert _counts(fv, fo, ico.vertices) == (30, 0, 30)


def test_mixed_polygons_and_masses():
    # a quad, a triangle and a pentagon sharing edges, in the plane
    pos = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 0.5, 0], [2, 2, 0], [1, 2.5, 0], [0, 2, 0]],
                   float)
    fv = np.array([0, 1, 2, 3, 1, 4, 2, 3, 2, 5, 6, 7])
    fo = np.array([0, 4, 7, 12])
    s = build_springs(fv, fo, pos)
    assert s.count_of(STRUCTURAL) == 10
    assert s.count_of(SHEAR) == 2 + 5
    areas = polygon_areas(fv, fo, pos)
    np.testing.assert_allclose(areas[:2], [1.0, 0.5])
    m = vertex_masses(fv, fo, pos, 0.2)
    np.testing.assert_allclose(m.sum(), 0.2 * areas.sum())
    np.testing.assert_allclose(m[0], 0.2 * 1.0 / 4)


def test_grid_structural_spring_constant_equals_modulus():
    for n in (4, 9):
        pos, fv, fo = grid_polygons(n, n, 0.7, 0.7)
        s = build_springs(fv, fo, pos)
        k, kd = spring_constants(s, (100.0, 10.0, 1.0), (0.5, 0.0, 0.0))
        interior = (s.type == STRUCTURAL) & (s.area > 0.75 * s.rest ** 2)
        np.testing.assert_allclose(k[interior], 100.0)  # independent of spacing
        np.testing.assert_allclose(kd[interior], 0.5)
        np.testing.assert_allclose(k[s.type == SHEAR], 10.0 / 4)


# -- materials -----------------------------------------------------------------------

def test_presets_and_material_json(tmp_path):
    assert {"cotton", "denim", "silk", "jersey"} <= set(PRESETS)
    assert PRESETS["denim"].areal_density > PRESETS["cotton"].areal_density > PRESETS["silk"].areal_density
    good = PRESETS["cotton"].to_dict()
    good.pop("name")
    path = tmp_path / "linen.json"
    path.write_text(json.dumps(good))
    mat = load_material(path)
    assert mat.name == "linen" and mat.stretch_stiffness == PRESETS["cotton"].stretch_stiffness
    assert resolve_material(str(path)) == mat
    for bad in ({**good, "areal_density": float("nan")}, {**good, "shear_stiffness": -1.0},
                {k: v for k, v in good.items() if k != "bend_stiffness"}, {**good, "colour": "red"}):
        path.write_text(json.dumps(bad))
        with pytest.raises(InputError):
            load_material(path)
    path.write_text('{"areal_density": NaN}')
    with pytest.raises(InputError):
        load_material(path)
    path.write_text("{not json")
    with pytest.raises(InputError):
        load_material(path)
    with pytest.raises(InputError):
        resolve_material("tweed")
    with pytest.raises(InputError):
        Material("x", 0.1, 1, 1, 1, 1, 1, float("inf"))


# -- solver ----------------------------------------------------------------------------

def _free_particles(n=5, seed=0):
    rng = np.random.default_rng(seed)
    pos = rng.uniform(-1, 1, size=(n, 3))
    return Model.create(pos, np.zeros((0, 2)), [], [], [], [], np.full(n, 0.1)), pos, rng


def test_undamped_free_fall_is_exact():
    model, x0, rng = _free_particles()
    v0 = rng.normal(size=x0.shape)
    g = np.array([0.3, -9.81, 0.1])
    dt = 1.0 / 240
    solver = SolverVerlet(model, VerletSettings(gravity=tuple(g), air_damping=0.0))
    state = solver.init_state(dt, vel=v0)
    for step in range(1, 31):
        solver.step(state, dt)
        t = step * dt
        np.testing.assert_allclose(state.pos, x0 + v0 * t + 0.5 * g * t * t, rtol=0, atol=1e-12)
    # and in fused frames of several substeps
    state = solver.init_state(dt, vel=v0)
    solver.step_frame(state, 4 * dt, substeps=4)
    solver.step_frame(state, 4 * dt, substeps=4)
    t = 8 * dt
    np.testing.assert_allclose(state.pos, x0 + v0 * t + 0.5 * g * t * t, rtol=0, atol=1e-12)
    assert state.time == pytest.approx(t) and state.step_count == 8


def _spring_pair(kd=0.0):
    pos = np.array([[0.0, 0.0, 0.0], [1.3, 0.0, 0.0]])
    return Model.create(pos, [[0, 1]], [1.0], [50.0], [kd], [STRUCTURAL], [1.0, 1.0])


def _pair_energy(model, state):
    v = state.velocity()
    length = np.linalg.norm(state.pos[1] - state.pos[0])
    return 0.5 * np.sum(model.mass[:, None] * v * v) + 0.5 * 50.0 * (length - 1.0) ** 2


@pytest.mark.parametrize("air", [0.0, 2.0])
def test_air_damping_makes_oscillation_energy_decay(air):
    model = _spring_pair()
    settings = VerletSettings(gravity=(0, 0, 0), air_damping=air, strain_limit=10.0, stability_safety=0)
    solver = SolverVerlet(model, settings)
    dt = 1e-3
    state = solver.init_state(dt)
    e0 = _pair_energy(model, state)
    for _ in range(2000):
        solver.step(state, dt)
    e1 = _pair_energy(model, state)
    if air == 0.0:
        assert abs(e1 / e0 - 1) < 0.02  # Verlet conserves energy up to O(dt^2) wiggles
    else:
        assert e1 < 0.05 * e0  # exp(-2 * 2 s) ~ 0.018


def _hanging_cloth(n=8, parallel=False, **kw):
    pos, fv, fo = grid_polygons(n, n, 0.4, 0.4)
    pos = pos[:, [0, 2, 1]]  # vertical cloth in the XY plane
    top = np.nonzero(pos[:, 1] == pos[:, 1].max())[0]
    pins = top[[0, -1]]
    model = Model.from_polygons(fv, fo, pos, "cotton", pin_indices=pins)
    settings = VerletSettings(substeps=8, air_damping=2.0, parallel=parallel, **kw)
    return model, SolverVerlet(model, settings)


def test_cloth_pinned_at_two_corners_comes_to_rest():
    model, solver = _hanging_cloth()
    state = solver.init_state(1 / 480)
    pins0 = state.pos[model.pin_indices].copy()
    for _ in range(600):
        solver.step_frame(state, 1 / 60)
    assert np.all(np.isfinite(state.pos))
    assert solver.max_speed(state) < 1e-3
    assert np.array_equal(state.pos[model.pin_indices], pins0)
    assert state.pos[:, 1].min() < pins0[:, 1].min() - 0.2  # it did fall
    assert solver.max_stretch(state) <= model.max_strain + 1e-3


def test_pins_follow_moving_targets():
    model, solver = _hanging_cloth(n=5)
    state = solver.init_state(1 / 480)
    target = state.pos[model.pin_indices] + np.array([0.05, 0.0, 0.0])
    state.set_pin_target(target)
    solver.step_frame(state, 1 / 60)
    np.testing.assert_allclose(state.pos[model.pin_indices], target, atol=1e-15)
    np.testing.assert_allclose(state.velocity()[model.pin_indices], [[0.05 * 60, 0, 0]] * 2, rtol=1e-9)


def _drape(n, frames, parallel=False, wrap=False):
    pos, fv, fo = grid_polygons(n, n, 1.0, 1.0)
    pos[:, 1] = 0.5
    model = Model.from_polygons(fv, fo, pos, "cotton")
    sphere = SphereCollider([[0.0, 0.0, 0.0]], [0.3], skin=0.01, friction=0.5)
    if wrap:  # hide sphere_arrays: the solver must call project() every substep
        class Plain:
            def project(self, x, x_prev, inv_mass):
                sphere.project(x, x_prev, inv_mass)
        colliders = [Plain()]
    else:
        colliders = [sphere]
    settings = VerletSettings(substeps=10, bend_strain_limit=0.10, parallel=parallel)
    solver = SolverVerlet(model, settings, colliders)
    state = solver.init_state(1 / 600)
    for _ in range(frames):
        solver.step_frame(state, 1 / 60)
    return model, solver, state, sphere


def test_sphere_drape_small():
    model, solver, state, sphere = _drape(20, 120)
    assert np.all(np.isfinite(state.pos))
    assert sphere.signed_distance(state.pos).min() >= 0.0
    assert solver.max_stretch(state) <= 0.10
    assert state.pos[:, 1].min() < -0.1  # it draped over, not stuck on top
    assert solver.max_speed(state) < 0.5


def test_determinism_and_python_collider_path():
    _, _, a, _ = _drape(12, 20)
    _, _, b, _ = _drape(12, 20)
    assert a.pos.tobytes() == b.pos.tobytes() and a.pos_prev.tobytes() == b.pos_prev.tobytes()
    _, _, c, _ = _drape(12, 20, wrap=True)  # same order of operations through project()
    assert a.pos.tobytes() == c.pos.tobytes()


def test_bad_inputs():
    pos, fv, fo = grid_polygons(3, 3)
    with pytest.raises(InputError):
        Model.from_polygons(fv, fo, pos, "cotton", pin_indices=[0, 0])
    with pytest.raises(InputError):
        Model.from_polygons(fv, fo[:-1], pos, "cotton")
    bad = pos.copy()
    bad[0, 0] = np.nan
    with pytest.raises(InputError):
        Model.from_polygons(fv, fo, bad, "cotton")
    with pytest.raises(InputError):
        SphereCollider([[0, 0, 0]], [-1.0])


# -- body-mesh contacts solved inside the strain-limit iterations (drape_step) ----------

class _Contacts:
    """A fused mesh-contact collider (the interface SolverVerlet looks for)."""

    def __init__(self, mesh, max_push=1.0, reach=0.002, damping=0.0):
        self.mesh, self.max_push, self.reach, self.damping = mesh, max_push, reach, damping

    def contact_args(self):
        m = self.mesh
        return m.grid, m.skin, self.reach, m.friction, self.max_push, self.damping


def _box_body(skin=0.002, friction=0.5):
    from vfit_engine.collide.body_mesh import MeshCollider

    box = trimesh.creation.box(extents=(0.4, 0.2, 0.4))  # top face at y = 0.1
    return MeshCollider(box.vertices, box.faces, skin=skin, friction=friction)


def _one_particle_model(y, x=0.0):
    pos = np.array([[x, y, 0.0], [x + 0.05, 1.0, 0.0]])  # a second, pinned particle far away
    return Model.create(pos, np.zeros((0, 2), np.int64), np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0, np.int64),
                        np.array([0.01, 0.01]), pin_indices=[1])


def test_contact_particle_rests_on_the_surface_at_the_skin():
    body = _box_body()
    model = _one_particle_model(0.1 + body.skin)
    solver = SolverVerlet(model, VerletSettings(substeps=4, air_damping=0.0), [_Contacts(body)])
    state = solver.init_state(1 / 240)
    for _ in range(60):
        solver.step_frame(state, 1 / 60)
    # gravity presses it in each substep, the contact puts it back: it stays at the skin, at rest
    assert state.pos[0] == pytest.approx([0.0, 0.1 + body.skin, 0.0], abs=1e-12)
    assert np.all(np.abs(state.pos[0] - state.pos_prev[0]) < 1e-12)
    assert solver.contact_queries > 0


def test_contact_push_is_limited_and_adds_no_velocity():
    body = _box_body()
    model = _one_particle_model(0.1 - 0.005)  # 5 mm inside the top face
    solver = SolverVerlet(model, VerletSettings(substeps=1, gravity=(0.0, 0.0, 0.0), air_damping=0.0),
                          [_Contacts(body, max_push=0.001)])
    state = solver.init_state(0.001)
    ys = []
    for _ in range(10):
        solver.step(state, 0.001)
        ys.append(state.pos[0, 1])
    # out by 1 mm per substep until at the skin, then still
    expect = np.minimum(0.095 + 0.001 * np.arange(1, 11), 0.1 + body.skin)
    assert np.allclose(ys, expect, atol=1e-12)
    assert np.all(np.abs(state.pos[0] - state.pos_prev[0]) < 1e-12)


def test_contact_friction_slows_a_sliding_particle():
    # a particle sliding along the top face: Coulomb friction takes mu * g * dt off its speed per step
    for mu, moving in ((0.0, True), (0.5, False)):
        body = _box_body(friction=mu)
        model = _one_particle_model(0.1 + body.skin, x=-0.1)
        solver = SolverVerlet(model, VerletSettings(substeps=10, air_damping=0.0), [_Contacts(body)])
        state = solver.init_state(1 / 600, vel=[0.5, 0.0, 0.0])
        for _ in range(12):  # 0.2 s: mu g t = 0.98 m/s > 0.5 m/s
            solver.step_frame(state, 1 / 60)
        speed = np.linalg.norm(state.pos[0] - state.pos_prev[0]) * 600
        assert (speed > 0.49) == moving
        assert state.pos[0, 1] == pytest.approx(0.1 + body.skin, abs=1e-12)


def test_sheet_on_sphere_jointly_limited_and_outside():
    from vfit_engine.collide.body_mesh import MeshCollider

    sphere = trimesh.creation.icosphere(subdivisions=4, radius=0.1)
    body = MeshCollider(sphere.vertices, sphere.faces, skin=0.002, friction=0.3)
    pos, fv, fo = grid_polygons(16, 16, 0.3, 0.3)
    pos = np.ascontiguousarray(pos[:, [0, 2, 1]] - [0.15, -0.105, 0.15])  # horizontal, 5 mm above the top
    model = Model.from_polygons(fv, fo, pos, "cotton")
    st = VerletSettings(substeps=8, air_damping=1.0, strain_limit=0.02, bend_strain_limit=0.02,
                        strain_limit_iterations=10, strain_limit_relaxation=1.5)
    solver = SolverVerlet(model, st, [_Contacts(body, max_push=0.005)])
    state = solver.init_state(1 / 480)
    for _ in range(60):
        solver.step_frame(state, 1 / 60)
    d, _, _, _ = body.query(state.pos, max_out=1.0, max_in=1.0)
    assert np.all(np.isfinite(state.pos)) and d.min() > 0.002 * (1 - 1e-6) - 1e-9
    assert model.max_stretch(state.pos) < 0.05
    assert state.pos[:, 1].min() < 0.0  # it draped over the sphere rather than staying flat


# -- untangling --------------------------------------------------------------------------

def test_untangle_moves_a_sheet_out_of_the_body_within_the_limit():
    from vfit_engine.collide.body_mesh import MeshCollider
    from vfit_engine.geometry import vertex_normals
    from vfit_engine.sim.untangle import untangle

    sphere = trimesh.creation.icosphere(subdivisions=4, radius=0.1)
    body = MeshCollider(sphere.vertices, sphere.faces, skin=0.002)
    garment = trimesh.creation.uv_sphere(radius=0.099, count=[24, 24])
    fv, fo = _tri_polys(garment.faces)
    pos = np.ascontiguousarray(garment.vertices)
    # vertex normals of a sphere point outward (either winding is detected)
    assert np.all(np.abs(np.einsum("ij,ij->i", vertex_normals(pos, fv, fo), pos / 0.099)) > 0.9)
    springs = build_springs(fv, fo, pos)
    sel = springs.type == STRUCTURAL
    idx, rest = springs.indices[sel], springs.rest[sel]
    out, info = untangle(pos, fv, fo, body, idx, rest * 1.05, skin=0.002)
    d, _, _, _ = body.query(out, max_out=1.0, max_in=1.0)
    assert info["inside_before"] == len(pos) and info["inside_after"] == 0
    assert d.min() >= 0.002 * (1 - 1e-6)
    strain = np.linalg.norm(out[idx[:, 1]] - out[idx[:, 0]], axis=1) / rest - 1
    assert strain.max() < 0.05 + 1e-9
    assert np.array_equal(pos, garment.vertices)  # the input is not modified
