"""SolverVerlet, Model, springs-from-topology and materials."""

import numpy as np
import pytest
import trimesh

from vfit_engine.collide.spheres import SphereCollider
from vfit_engine.errors import InputError
from vfit_engine.sim.springs import (BEND, SHEAR, STRUCTURAL, build_springs, grid_polygons, polygon_areas,
                                         spring_constants, vertex_masses)
from vfit_engine.sim.model import Model
from vfit_engine.sim.contact_points import contact_points
from vfit_engine.sim.solver_verlet import ContactSettings, SolverVerlet, VerletSettings


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
    """Two particles and an explicit Hooke spring (a bend spring: with ``bend_limit=None`` it is no
    constraint), stretched 30 %."""
    pos = np.array([[0.0, 0.0, 0.0], [1.3, 0.0, 0.0]])
    return Model.create(pos, [[0, 1]], [1.0], [50.0], [kd], [BEND], [1.0, 1.0])


def _pair_energy(model, state):
    v = state.velocity()
    length = np.linalg.norm(state.pos[1] - state.pos[0])
    return 0.5 * np.sum(model.mass[:, None] * v * v) + 0.5 * 50.0 * (length - 1.0) ** 2


@pytest.mark.parametrize("air", [0.0, 2.0])
def test_air_damping_makes_oscillation_energy_decay(air):
    model = _spring_pair()
    settings = VerletSettings(gravity=(0, 0, 0), air_damping=air, bend_limit=None, stability_safety=0)
    solver = SolverVerlet(model, settings)
    assert solver.constraint_count == 0
    dt = 1e-3
    state = solver.init_state(dt)
    e0 = _pair_energy(model, state)
    lengths = []
    for _ in range(2000):
        solver.step(state, dt)
        lengths.append(np.linalg.norm(state.pos[1] - state.pos[0]))
    e1 = _pair_energy(model, state)
    assert min(lengths) < 0.8  # it oscillated (through its rest length), as a spring of 50 N/m does
    if air == 0.0:
        assert abs(e1 / e0 - 1) < 0.02  # Verlet conserves energy up to O(dt^2) wiggles
    else:
        assert e1 < 0.05 * e0  # exp(-2 * 2 s) ~ 0.018


def _hanging_cloth(n=8, **kw):
    pos, fv, fo = grid_polygons(n, n, 0.4, 0.4)
    pos = pos[:, [0, 2, 1]]  # vertical cloth in the XY plane
    top = np.nonzero(pos[:, 1] == pos[:, 1].max())[0]
    pins = top[[0, -1]]
    model = Model.from_polygons(fv, fo, pos, "cotton", pin_indices=pins)
    settings = VerletSettings(substeps=8, air_damping=2.0, **kw)
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


SPHERE_R = 0.3


def _sphere_drape(n, frames, project=False):
    """A flat sheet dropped onto a sphere: in the kernel (``spheres``, vertices and surface points)
    or, with ``project``, through a collider's ``project`` after every substep."""
    pos, fv, fo = grid_polygons(n, n, 1.0, 1.0)
    pos[:, 1] = 0.5
    model = Model.from_polygons(fv, fo, pos, "cotton")
    settings = VerletSettings(substeps=10)
    if project:
        sphere = SphereCollider([[0.0, 0.0, 0.0]], [SPHERE_R], skin=0.01, friction=0.5)
        solver = SolverVerlet(model, settings, colliders=[sphere])
    else:
        solver = SolverVerlet(model, settings, ContactSettings(friction=0.5), spheres=[[0.0, 0.0, 0.0, SPHERE_R]],
                              points=contact_points(fv, fo, pos, spacing=0.03))
    state = solver.init_state(1 / 600)
    for _ in range(frames):
        solver.step_frame(state, 1 / 60)
    return model, solver, state, fv, fo


def _sphere_gap(points):
    return np.linalg.norm(points, axis=1) - SPHERE_R


def test_sphere_drape_small():
    from vfit_engine.drape.metrics import surface_samples
    from vfit_engine.io.meshdata import MeshData

    model, solver, state, fv, fo = _sphere_drape(20, 120)
    assert np.all(np.isfinite(state.pos))
    skin = solver.contact.skin
    assert _sphere_gap(state.pos).min() >= skin * (1 - 1e-6)  # the vertices keep their clearance
    tris = MeshData(state.pos, fo, fv).triangles()
    # and the whole surface between them is out too (5 cm triangles on a 30 cm sphere would sag
    # ~1 mm into it between vertices held out alone)
    assert _sphere_gap(surface_samples(state.pos, tris, 8)).min() >= 0.0
    assert solver.max_stretch(state) <= 0.10
    assert state.pos[:, 1].min() < -0.1  # it draped over, not stuck on top
    assert solver.max_speed(state) < 0.5


def test_sphere_drape_is_deterministic_and_colliders_project():
    a = _sphere_drape(12, 20)[2]
    b = _sphere_drape(12, 20)[2]
    assert a.pos.tobytes() == b.pos.tobytes() and a.pos_prev.tobytes() == b.pos_prev.tobytes()
    # the same drape through a collider's project() after every substep: deterministic, outside its skin
    c = _sphere_drape(12, 20, project=True)[2]
    d = _sphere_drape(12, 20, project=True)[2]
    assert c.pos.tobytes() == d.pos.tobytes()
    assert _sphere_gap(c.pos).min() >= 0.01 * SPHERE_R * (1 - 1e-9) and c.pos[:, 1].min() < 0.2
    assert not np.allclose(c.pos, a.pos, atol=1e-3)  # a different contact model: not the same result


def test_two_threads_give_the_one_thread_result():
    """The kernel runs the cloth's halves on two threads: a 24 x 24 sheet (split: at least MIN_SPLIT
    vertices) drapes to the same bits on one thread as on two, and its halves are numbered apart."""
    import numba

    from vfit_engine.sim.partition import MIN_SPLIT

    assert 24 * 24 >= MIN_SPLIT
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        _, solver, one, _, _ = _sphere_drape(24, 15)
        numba.set_num_threads(min(2, numba.config.NUMBA_NUM_THREADS))
        two = _sphere_drape(24, 15)[2]
    finally:
        numba.set_num_threads(before)
    assert one.pos.tobytes() == two.pos.tobytes() and one.pos_prev.tobytes() == two.pos_prev.tobytes()
    first, second, across = solver.segment_sizes
    assert min(first, second) > 0.45 * solver.constraint_count and across > 0  # two halves, a short cut
    assert np.all(np.isfinite(one.pos)) and _sphere_gap(one.pos).min() > 0


def _sheet_on_the_ground(ground, slide=0.0, frames=60):
    """A 30 cm sheet of 10 x 10 vertices dropped flat from 3 cm above the ground plane at y = ``ground``,
    moving sideways (x) at ``slide`` m/s."""
    pos, fv, fo = grid_polygons(10, 10, 0.3, 0.3)
    pos[:, 1] = 0.03 if ground is None else ground + 0.03
    model = Model.from_polygons(fv, fo, pos, "cotton")
    solver = SolverVerlet(model, VerletSettings(substeps=8), ContactSettings(friction=0.8), ground=ground,
                          points=contact_points(fv, fo, pos, spacing=0.015))
    state = solver.init_state(1 / 480, vel=[slide, 0.0, 0.0])
    for _ in range(frames):
        solver.step_frame(state, 1 / 60)
    return pos, solver, state


def test_sheet_dropped_on_the_ground_rests_on_it_at_its_clearance():
    """Free fall, then the ground: every vertex at rest at its clearance above the plane (the contact's
    half-space y >= ground + skin, met exactly), where it landed (nothing to push it sideways)."""
    ground = -0.8
    pos, solver, state = _sheet_on_the_ground(ground)
    assert solver.ground == ground
    skin = solver.contact.skin
    np.testing.assert_allclose(state.pos[:, 1], ground + skin, atol=1e-9)
    np.testing.assert_allclose(state.pos[:, [0, 2]], pos[:, [0, 2]], atol=1e-9)
    assert solver.max_speed(state) < 1e-6
    # without the ground the same sheet falls on: y = y0 - g t^2 / 2 less the air's damping
    _, free, fell = _sheet_on_the_ground(None)
    assert free.ground is None and fell.pos[:, 1].max() < -1.0


def test_friction_on_the_ground_stops_a_sliding_sheet():
    """A sheet landing at 0.5 m/s sideways slides on the ground and stops: Coulomb friction (mu 0.8) takes
    mu g per second at least, so it stops within v^2 / (2 mu g) = 1.6 cm of where it touched down."""
    ground = 0.0
    pos, _, state = _sheet_on_the_ground(ground, slide=0.5, frames=90)
    moved = state.pos[:, 0] - pos[:, 0]
    fall = np.sqrt(2 * 0.03 / 9.81)  # before touching down it drifted slide x fall time (less the air's damping)
    assert np.all(moved > 0) and np.all(moved < 0.5 * fall + 0.5 ** 2 / (2 * 0.8 * 9.81) + 1e-3)
    assert np.all(np.abs(state.pos[:, 1] - 0.002) < 1e-6) and np.abs(state.velocity()).max() < 1e-6


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
    model = Model.from_polygons(fv, fo, pos, "cotton")
    with pytest.raises(ValueError, match="spheres"):
        SolverVerlet(model, spheres=np.zeros((2, 3)))
    with pytest.raises(ValueError, match="ground"):
        SolverVerlet(model, ground=np.nan)
    for bad_settings in (dict(substeps=0), dict(gravity=(0.0, np.nan, 0.0)), dict(compression=1.0),
                         dict(shear_limit_deg=90.0), dict(slack=-0.1), dict(air_damping=-1.0)):
        with pytest.raises(ValueError):
            VerletSettings(**bad_settings)
    solver = SolverVerlet(model)
    state = solver.init_state(0.01)
    with pytest.raises(ValueError, match="dt"):
        solver.step(state, 0.0)
    with pytest.raises(ValueError):
        solver.init_state(0.01, pos=np.zeros((4, 3)))


# -- shear: corner-angle limits and the shear springs that restore the angles ---------------------

QUAD_SIDE = 0.05


def _sheared_quad(deg):
    """A flat square quad of side 5 cm sheared by ``deg`` degrees (side lengths kept)."""
    s, c = np.sin(np.radians(deg)), np.cos(np.radians(deg))
    a = QUAD_SIDE
    return np.array([[0.0, 0.0, 0.0], [a, 0.0, 0.0], [a + a * s, 0.0, a * c], [a * s, 0.0, a * c]])


def _quad_solver():
    fv, fo = np.array([0, 1, 2, 3]), np.array([0, 4])
    model = Model.from_polygons(fv, fo, _sheared_quad(0.0), "cotton")
    return model, SolverVerlet(model, VerletSettings(gravity=(0.0, 0.0, 0.0))), fv, fo


def _shear_deg(pos, fv, fo):
    from vfit_engine.drape.metrics import corner_angles

    return float(np.max(np.abs(np.degrees(corner_angles(pos, fv, fo)) - 90.0)))


def test_sheared_quad_returns_to_its_rest_angle():
    """A free quad sheared by 8 degrees (inside the 10 degree shear limit) is pulled back to its
    square by the compliant shear springs, at its own size (not by shrinking)."""
    model, solver, fv, fo = _quad_solver()
    state = solver.init_state(1 / 480, pos=_sheared_quad(8.0))
    assert _shear_deg(state.pos, fv, fo) == pytest.approx(8.0)
    for _ in range(30):
        solver.step_frame(state, 1 / 60)
    assert _shear_deg(state.pos, fv, fo) < 1.0
    side = np.linalg.norm(state.pos - np.roll(state.pos, 1, axis=0), axis=1)
    np.testing.assert_allclose(side, QUAD_SIDE, rtol=0.015)  # the stretch constraints' free band
    assert solver.max_speed(state) < 0.01


def test_quad_sheared_beyond_the_limit_is_brought_within_it_at_once():
    model, solver, fv, fo = _quad_solver()
    limit = solver.settings.shear_limit_deg
    state = solver.init_state(1 / 480, pos=_sheared_quad(30.0))
    solver.step(state, 1 / 480)  # one substep
    assert _shear_deg(state.pos, fv, fo) <= limit + 0.5
    for _ in range(10):
        solver.step_frame(state, 1 / 60)
        assert _shear_deg(state.pos, fv, fo) <= limit + 0.5
    assert _shear_deg(state.pos, fv, fo) < 0.5 * limit
    assert model.max_stretch(state.pos) <= solver.settings.slack + 1e-3


# -- the sweep order and the bands round openings --------------------------------------------------

def test_sweep_from_the_pins_passes_their_pull_down():
    """Constraints swept outward from the pins carry a pull on the pins down the cloth within a
    substep's few sweeps (Gauss-Seidel along the load path); swept from the far end, the pull
    stays at the top and stretches it. (With the solver's default sweeps: with 3, the compliant bend
    limits pass too little within one substep for the order to show.)"""
    pos, fv, fo = grid_polygons(4, 13, 0.15, 0.6)  # rows 5 cm apart along z
    top = np.flatnonzero(pos[:, 2] == pos[:, 2].max())
    bottom = np.flatnonzero(pos[:, 2] == pos[:, 2].min())
    worst = []
    for start in (top, bottom):
        model = Model.from_polygons(fv, fo, pos, "cotton", pin_indices=top)
        solver = SolverVerlet(model, VerletSettings(gravity=(0.0, 0.0, 0.0)))
        solver.sweep_from(start)
        state = solver.init_state(1 / 480)
        state.set_pin_target(pos[top] + [0.0, 0.0, 0.01])  # the pins pulled 1 cm away from the cloth
        solver.step(state, 1 / 480)
        worst.append(model.max_stretch(state.pos))
    assert worst[0] < 0.8 * worst[1]


def _strip(zone_strain=None, admit=False):
    """A 4 x 20 cm strip pinned at both ends, the ends pulled 8 % apart (or, with ``admit``, the strip
    started 8 % longer with the bands opened to that); returns the strain along it, lower / upper half."""
    pos, fv, fo = grid_polygons(5, 21, 0.04, 0.2)
    ends = np.flatnonzero(np.abs(pos[:, 2]) == pos[:, 2].max())
    model = Model.from_polygons(fv, fo, pos, "cotton", pin_indices=ends)
    solver = SolverVerlet(model, VerletSettings(gravity=(0.0, 0.0, 0.0), air_damping=5.0))
    lower = np.flatnonzero(pos[:, 2] <= 1e-9)
    longer = pos * [1.0, 1.0, 1.08]
    if zone_strain is not None:
        solver.allow_stretch(lower, zone_strain)
    if admit:
        solver.admit(longer, np.arange(len(pos)))
    state = solver.init_state(1 / 480, pos=longer if admit else None)
    state.set_pin_target(longer[model.pin_indices])
    for _ in range(200):
        solver.step_frame(state, 1 / 60)
    assert solver.max_speed(state) < 1e-6
    i, j = model.spring_indices.T
    along = (model.spring_type == STRUCTURAL) & (pos[i, 0] == pos[j, 0])
    strain = model.spring_strain(state.pos)
    return (strain[along & (pos[i, 2] <= 1e-9) & (pos[j, 2] <= 1e-9)].mean(),
            strain[along & (pos[i, 2] >= -1e-9) & (pos[j, 2] >= -1e-9)].mean())


def test_allow_stretch_lets_the_zone_take_the_stretch():
    """An opening the body forces wider may stretch as far as it must, and so may the cloth round
    it; the rest of the cloth keeps its bands."""
    lo, up = _strip()
    assert 0.05 < lo < 0.11 and 0.05 < up < 0.11 and abs(lo - up) < 0.03  # shared between the halves
    lo, up = _strip(zone_strain=0.12)
    assert lo > 0.10 and up < 0.04  # the lower half, allowed 12 %, takes most of the 8 %


def test_admit_keeps_a_start_the_body_forced_wider():
    """Bands widened to admit a start 8 % longer: the strip stays as it started (nothing pulls it back
    towards a size the pins do not let it have, nor stretches it further)."""
    lo, up = _strip(admit=True)
    assert lo == pytest.approx(0.08, abs=0.005) and up == pytest.approx(0.08, abs=0.005)


# -- contacts with a body mesh, solved in the constraint loop (kernels/cloth.py) --------------------

def _box_body():
    from vfit_engine.collide.body_mesh import MeshCollider

    box = trimesh.creation.box(extents=(0.4, 0.2, 0.4))  # top face at y = 0.1
    return MeshCollider(box.vertices, box.faces)


def _one_particle_model(y, x=0.0):
    pos = np.array([[x, y, 0.0], [x + 0.05, 1.0, 0.0]])  # a second, pinned particle far away
    return Model.create(pos, np.zeros((0, 2), np.int64), np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0, np.int64),
                        np.array([0.01, 0.01]), pin_indices=[1])


def test_contact_particle_rests_on_the_surface_at_the_skin():
    body = _box_body()
    contact = ContactSettings(skin=0.002)
    model = _one_particle_model(0.1 + contact.skin)
    solver = SolverVerlet(model, VerletSettings(substeps=4, air_damping=0.0), contact, body=body)
    state = solver.init_state(1 / 240)
    for _ in range(60):
        solver.step_frame(state, 1 / 60)
    # gravity presses it in each substep, the contact puts it back: it stays at the skin, at rest
    assert state.pos[0] == pytest.approx([0.0, 0.1 + contact.skin, 0.0], abs=1e-12)
    assert np.all(np.abs(state.pos[0] - state.pos_prev[0]) < 1e-12)
    assert solver.contact_queries > 0


def test_contact_push_is_limited_and_adds_no_velocity():
    body = _box_body()
    contact = ContactSettings(skin=0.002)
    model = _one_particle_model(0.1 - 0.005)  # 5 mm inside the top face
    solver = SolverVerlet(model, VerletSettings(substeps=1, gravity=(0.0, 0.0, 0.0), air_damping=0.0), contact,
                          body=body)
    solver.max_push = 0.001
    state = solver.init_state(0.001)
    ys = []
    for _ in range(10):
        solver.step(state, 0.001)
        ys.append(state.pos[0, 1])
        assert np.all(np.abs(state.pos[0] - state.pos_prev[0]) < 1e-12)  # no velocity from the pushes
    # out by 1 mm per substep until at the skin, then still
    expect = np.minimum(0.095 + 0.001 * np.arange(1, 11), 0.1 + contact.skin)
    np.testing.assert_allclose(ys, expect, atol=1e-12)


def test_contact_friction_slows_a_sliding_particle():
    # a particle sliding along the top face: Coulomb friction takes mu * g * dt off its speed per step
    body = _box_body()
    for mu, moving in ((0.0, True), (0.5, False)):
        contact = ContactSettings(skin=0.002, friction=mu)
        model = _one_particle_model(0.1 + contact.skin, x=-0.1)
        solver = SolverVerlet(model, VerletSettings(substeps=10, air_damping=0.0), contact, body=body)
        state = solver.init_state(1 / 600, vel=[0.5, 0.0, 0.0])
        for _ in range(12):  # 0.2 s: mu g t = 0.98 m/s > 0.5 m/s
            solver.step_frame(state, 1 / 60)
        speed = np.linalg.norm(state.pos[0] - state.pos_prev[0]) * 600
        assert (speed > 0.49) == moving
        assert state.pos[0, 1] == pytest.approx(0.1 + contact.skin, abs=1e-12)


def _particle_on_sphere(deg, radius, skin, stick):
    """A solver with one free particle at rest on a sphere collider ``deg`` degrees from its top, at the skin."""
    a = np.radians(deg)
    at = (radius + skin) * np.array([np.sin(a), np.cos(a), 0.0])
    pos = np.array([at, at + [0.0, 1.0, 0.0]])  # a second, pinned particle far away
    model = Model.create(pos, np.zeros((0, 2), np.int64), np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0, np.int64),
                         np.array([0.01, 0.01]), pin_indices=[1])
    contact = ContactSettings(skin=skin, friction=0.8, damping=60.0, stick=stick)
    solver = SolverVerlet(model, VerletSettings(substeps=16, air_damping=0.0), contact,
                          spheres=np.array([[0.0, 0.0, 0.0, radius]]))
    return solver, solver.init_state(1 / 480)


def test_stick_holds_cloth_on_a_slope_where_velocity_friction_lets_it_creep():
    """A particle at rest on a sphere 30 degrees from its top (friction 0.8 > tan 30): friction on its velocity
    alone stops what each substep gained, but gravity's slide within the substep, g sin(30) dt^2, is kept: it
    creeps down ~0.7 mm per 1/30 s; with stick it stays where it lies."""
    moved = {}
    for stick in (False, True):
        solver, state = _particle_on_sphere(30.0, 0.1, 0.002, stick)
        start = state.pos[0].copy()
        for _ in range(10):
            solver.step_frame(state, 1 / 30)
        moved[stick] = np.linalg.norm(state.pos[0] - start)
    creep = 10 * 16 * 9.81 * 0.5 * (1 / 480) ** 2  # g sin(30) dt^2 per substep
    assert moved[False] == pytest.approx(creep, rel=0.1)
    assert moved[True] < 1e-9


def test_a_moving_body_carries_the_cloth_resting_on_it():
    """A particle resting on top of a sphere that sets off sideways at 0.5 m/s (SolverVerlet.body_moved with the
    spheres' velocity, every substep): friction and damping act relative to the sphere, which takes it along
    (it slips ~u / damping = 8 mm while it comes up to speed, then moves with the sphere); without the
    velocity the contact takes the sphere for still and holds the particle back: it slides off behind."""
    left, speed_end = {}, {}
    for carried in (False, True):
        solver, state = _particle_on_sphere(0.0, 0.1, 0.002, stick=True)
        speed = np.array([[0.5, 0.0, 0.0]])
        centre = np.zeros(3)
        for _ in range(10 * 16):
            centre = centre + speed[0] / 480
            solver.body_moved(0.001, spheres=np.array([[*centre, 0.1]]),
                              sphere_velocity=speed if carried else np.zeros((1, 3)))
            solver.step(state, 1 / 480)
        left[carried] = state.pos[0, 0] - centre[0]  # how far it lags behind the top
        speed_end[carried] = (state.pos[0, 0] - state.pos_prev[0, 0]) * 480
    assert -0.01 < left[True] < 0.0 and speed_end[True] == pytest.approx(0.5, abs=1e-3)
    assert left[False] < -0.05


def _icosphere_body(radius=0.1, subdivisions=4):
    from vfit_engine.collide.body_mesh import MeshCollider

    sphere = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    return MeshCollider(sphere.vertices, sphere.faces)


def test_sheet_on_sphere_limited_and_outside():
    from vfit_engine.drape.metrics import surface_penetration
    from vfit_engine.io.meshdata import MeshData

    body = _icosphere_body()
    pos, fv, fo = grid_polygons(16, 16, 0.3, 0.3)
    pos = np.ascontiguousarray(pos + [0.0, 0.105, 0.0])  # horizontal, 5 mm above the top
    model = Model.from_polygons(fv, fo, pos, "cotton")
    contact = ContactSettings()
    solver = SolverVerlet(model, VerletSettings(substeps=8, air_damping=1.0), contact, body=body,
                          points=contact_points(fv, fo, pos, spacing=0.015))
    state = solver.init_state(1 / 480)
    for _ in range(60):
        solver.step_frame(state, 1 / 60)
    d, _, _, _ = body.query(state.pos, max_out=1.0, max_in=1.0)
    assert np.all(np.isfinite(state.pos)) and d.min() > 0.9 * contact.skin
    surface = surface_penetration(body, state.pos, MeshData(state.pos, fo, fv).triangles())
    assert surface["surface_inside_percent"] == 0.0
    assert model.max_stretch(state.pos) < 0.05
    assert state.pos[:, 1].min() < 0.0  # it draped over the sphere rather than staying flat


def test_triangle_over_a_bump_is_pushed_out_by_its_surface_points():
    """A large cloth triangle whose corners are outside the body but whose middle the body pokes
    through: its surface contact points push the whole triangle out; held out at its vertices only,
    it stays cut by the body (what a vertex-only collider misses)."""
    from vfit_engine.drape.metrics import surface_penetration

    body = _icosphere_body(subdivisions=3)
    ang = np.radians([90.0, 210.0, 330.0])
    pos = np.stack([0.08 * np.cos(ang), np.full(3, 0.095), 0.08 * np.sin(ang)], axis=1)  # 5 mm below the top
    fv, fo = np.array([0, 2, 1]), np.array([0, 3])
    tris = fv.reshape(1, 3)
    d, _, _, _ = body.query(pos, max_out=1.0, max_in=1.0)
    assert d.min() > 0.02  # the corners are 2.4 cm out
    before = surface_penetration(body, pos, tris)
    assert before["surface_max_depth_mm"] > 4.0 and before["surface_inside_percent"] > 20.0
    after = {}
    for surface in (True, False):
        model = Model.from_polygons(fv, fo, pos, "cotton")
        points = contact_points(fv, fo, pos, spacing=0.015, surface=surface)
        solver = SolverVerlet(model, VerletSettings(gravity=(0.0, 0.0, 0.0)), body=body, points=points)
        state = solver.init_state(1 / 480)
        for _ in range(10):
            solver.step_frame(state, 1 / 60)
        after[surface] = surface_penetration(body, state.pos, tris)
        assert np.all(np.isfinite(state.pos)) and model.max_stretch(state.pos) <= solver.settings.slack + 1e-6
    assert after[True]["surface_inside_percent"] == 0.0 and after[True]["surface_max_depth_mm"] == 0.0
    assert after[False] == before  # its vertices never touched the body: nothing moved it


def test_contact_points_of_a_square():
    """A 10 cm square at 1.5 cm spacing: its 4 corners; 6 points inside each side and 9 on the fan's
    diagonal (ceil(L / spacing) - 1); the 36 interior lattice points of each of its two triangles
    (order ceil(14.1 / 1.5) = 10: 9 x 8 / 2); the midpoint of its other diagonal. Every point is a
    convex combination of its triangle's corners."""
    pos = np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.1, 0.0, 0.1], [0.0, 0.0, 0.1]])
    fv, fo = np.array([0, 1, 2, 3]), np.array([0, 4])
    pts = contact_points(fv, fo, pos, spacing=0.015)
    assert pts.vertex_count == 4 and pts.count == 4 + 4 * 6 + 9 + 2 * 36 + 1
    np.testing.assert_array_equal(pts.verts[:4], np.repeat(np.arange(4)[:, None], 3, axis=1))
    np.testing.assert_array_equal(pts.bary[:4], np.tile([1.0, 0.0, 0.0], (4, 1)))
    np.testing.assert_allclose(pts.bary.sum(axis=1), 1.0, atol=1e-15)
    assert np.all(pts.bary >= 0.0)
    p = pts.positions(pos)
    assert np.allclose(p[:, 1], 0.0) and p[:, [0, 2]].min() >= 0.0 and p[:, [0, 2]].max() <= 0.1 + 1e-15
    # no point twice, but the centre: the midpoint of the fan's diagonal 0-2 and of the other, 1-3
    # (the same place on a flat square, not on a bent quad)
    assert np.unique(np.round(p, 12), axis=0).shape[0] == pts.count - 1
    assert np.allclose(p[-1], [0.05, 0.0, 0.05]) and set(pts.verts[-1, :2]) == {1, 3}
    # the points along a side are spacing apart at most
    side = np.sort(p[(np.abs(p[:, 2]) < 1e-12), 0])
    assert side.size == 8 and np.diff(side).max() <= 0.015
    assert contact_points(fv, fo, pos, surface=False).count == 4


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


@pytest.mark.parametrize("plane", ["xz", "yz", "xy"])
def test_the_cloth_is_cut_in_two_halves_with_a_short_cut(plane):
    """A 30 x 30 sheet in any orientation splits into halves of 450 vertices across its width, and only the
    constraints along the cut (about one row of them) run after the two threads."""
    from vfit_engine.sim.partition import halves, segment_of, segments

    pos, fv, fo = grid_polygons(30, 30, 1.0, 1.0)  # in the x-z plane
    if plane == "yz":
        pos = pos[:, [1, 2, 0]]
    elif plane == "xy":
        pos = pos[:, [0, 2, 1]]
    order, rank, half = halves(pos)
    assert np.array_equal(rank[order], np.arange(pos.shape[0])) and np.array_equal(np.sort(order), rank[order])
    assert np.count_nonzero(half == 0) == np.count_nonzero(half == 1) == 450
    assert np.all(half[order][:450] == 0)  # numbered half by half
    e = build_springs(fv, fo, pos).indices
    _, bounds = segments(segment_of(half, e[:, 0], e[:, 1]))
    across = bounds[3] - bounds[2]
    assert 0 < across < 0.05 * bounds[3]
