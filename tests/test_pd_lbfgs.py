"""Quasi-Newton projective dynamics: the L-BFGS kernels (vfit_engine.kernels.lbfgs) and the step's energy
(vfit_engine.kernels.pd_energy) against NumPy references on seeded data, and the solver's analytic cases with
``PDSettings.history`` (vfit_engine.sim.solver_pd)."""
import math

import numpy as np
import pytest
from scipy import sparse

import naive_pd
from test_pd import I64, _a, _cloth, _contact_arrays, _elements, _planes, _points
from vfit_engine.kernels.bending import hinge_scratch
from vfit_engine.kernels.lbfgs import (dot3, first_loop, gradient, max_move, pair_energy, push_pair, second_loop,
                                      uzawa_energy)
from vfit_engine.kernels.pd import contact_friction, pd_rhs
from vfit_engine.sim.model import Model
from vfit_engine.sim.solver_pd import SolverPD
from vfit_engine.sim.solver_settings import PDSettings


@pytest.mark.parametrize("seed", [0, 1])
def test_gradient_is_the_matrix_product_less_the_right_hand_side(seed):
    rng = np.random.default_rng(seed)
    n = 30
    m = sparse.random(n, n, density=0.2, random_state=seed)
    a = sparse.csc_matrix(m + m.T + sparse.identity(n) * 5.0)
    a.sort_indices()
    x, b, nrm = rng.normal(size=(n, 3)), rng.normal(size=(n, 3)), rng.normal(size=(n, 3))
    lam = rng.uniform(-0.5, 1.0, n)  # a negative force is none
    g, g0 = np.zeros((n, 3)), np.zeros((n, 3))
    gradient(a.indptr, a.indices, a.data, x, b, lam, nrm, g, g0)
    np.testing.assert_allclose(g, a @ x - b, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(g0, g + np.maximum(lam, 0)[:, None] * nrm, rtol=1e-12, atol=1e-12)
    assert dot3(g, b) == pytest.approx(float(np.sum(g * b)), rel=1e-12)
    assert max_move(b) == pytest.approx(float(np.linalg.norm(b, axis=1).max()), rel=1e-12)


def _two_loop(g, pairs, solve):
    """The textbook L-BFGS direction (Nocedal & Wright, algorithm 7.4) with ``solve`` as the initial inverse
    Hessian, ``pairs`` oldest first."""
    q = g.ravel().copy()
    alphas = []
    for s, t in reversed(pairs):
        a = (s.ravel() @ q) / (s.ravel() @ t.ravel())
        alphas.append(a)
        q -= a * t.ravel()
    r = solve(q.reshape(g.shape)).ravel()
    for (s, t), a in zip(pairs, reversed(alphas)):
        bt = (t.ravel() @ r) / (s.ravel() @ t.ravel())
        r += s.ravel() * (a - bt)
    return r.reshape(g.shape)


@pytest.mark.parametrize("pushes", [0, 2, 4, 7])
def test_the_two_loops_and_a_solve_are_the_textbook_direction(pushes):
    """Through the ring of 4 slots (7 pushes wrap it): the kernels' direction is the textbook one of the 4
    newest pairs, and a pair with negative curvature is dropped."""
    rng = np.random.default_rng(pushes)
    n, m = 12, 4
    h = rng.normal(size=(3 * n, 3 * n))
    h = h @ h.T + 3 * n * np.eye(3 * n)  # the "true" Hessian the pairs sample
    a0 = np.diag(rng.uniform(1.0, 3.0, n))  # the PD matrix: one for the three coordinates

    def solve(v):
        return np.linalg.solve(a0, v)

    S, T, rho, alpha = np.zeros((m, n, 3)), np.zeros((m, n, 3)), np.zeros(m), np.zeros(m)
    newest, count, kept = m - 1, 0, []
    x_old, g_old = np.zeros((n, 3)), np.zeros((n, 3))
    for _ in range(pushes):
        s = rng.normal(size=(n, 3))
        x = x_old + s
        g = g_old + (h @ s.ravel()).reshape(n, 3)
        newest, count = push_pair(x, x_old, g, g_old, S, T, rho, newest, count)
        kept = (kept + [(s, g - g_old)])[-m:]
        x_old, g_old = x, g
    # a pair along which the energy is concave is not kept
    bad = rng.normal(size=(n, 3))
    assert push_pair(x_old + bad, x_old, g_old - bad, g_old, S, T, rho, newest, count) == (newest, count)
    assert count == min(pushes, m)
    g = rng.normal(size=(n, 3))
    r = g.copy()
    first_loop(r, S, T, rho, alpha, newest, count)
    r = solve(r)
    second_loop(r, S, T, rho, alpha, newest, count)
    np.testing.assert_allclose(r, _two_loop(g, kept, solve), rtol=1e-10, atol=1e-12)


def _energy_case(seed, corners=True):
    rng, model, x = _cloth(seed)
    n = model.particle_count
    dist, corners_, springs, hinges = _elements(rng, model)
    corners = corners_ if corners else corners_[:0]
    pts_v, pts_b = _points(rng, model)
    listed, planes = _planes(rng, x, pts_v, pts_b)
    c_n, c_h, c_n2, c_nq2, c_h2, c_list = _contact_arrays(listed, planes, len(pts_v))
    inv_mass = model.inv_mass.copy()
    free = inv_mass > 0
    mh2 = np.where(free, rng.uniform(0.1, 1.0, n), 0.0)
    w_c = np.where(free, rng.uniform(1.0, 20.0, n), 0.0)
    y = x + rng.normal(scale=0.002, size=x.shape)
    x0 = x + rng.normal(scale=0.002, size=x.shape)
    lam, nrm = rng.uniform(0, 0.1, n) * (rng.random(n) < 0.3), rng.normal(size=(n, 3))
    nrm /= np.linalg.norm(nrm, axis=1)[:, None]
    d_i, d_j = model.spring_indices[:, 0].copy(), model.spring_indices[:, 1].copy()
    dw = rng.uniform(0.0, 30.0, d_i.size) * (rng.random(d_i.size) < 0.7)
    elements = (_a(dist, 0, I64), _a(dist, 1, I64), _a(dist, 2), _a(dist, 3), _a(dist, 4), _a(corners, 0, I64),
                _a(corners, 1, I64), _a(corners, 2, I64), np.cos(_a(corners, 3)), np.cos(_a(corners, 4)),
                _a(corners, 5), _a(springs, 0, I64), _a(springs, 1, I64), _a(springs, 2), _a(springs, 3),
                _a(springs, 4), hinges[0], hinges[1], hinges[2])
    none = np.zeros(0, I64)
    args = (mh2, inv_mass, np.zeros(n)) + elements + (model.pin_indices, np.zeros(n + 1, I64), none, np.zeros(0),
                                                      pts_v, pts_b, c_n, c_h, c_n2, c_nq2, c_h2, c_list,
                                                      len(c_list), w_c, lam, nrm, x0)
    lists = (mh2, inv_mass, dist, corners, springs, hinges, w_c, planes, pts_v, pts_b, lam, nrm, x0)
    return x, y, args, lists, (d_i, d_j, dw), rng


def _energy(x, y, args, friction, damped, b=None):
    """The step's energy as the quasi-Newton iterations take it: the local step's, the friction's, the contact
    forces' and the damping's (each kernel returns its part); ``b`` (n, 3) out if given."""
    n = x.shape[0]
    lam, nrm, x0 = args[-3:]
    b = np.zeros((n, 3)) if b is None else b
    gap, count = np.zeros((n, 3)), np.zeros(n)
    e = pd_rhs(x, y, *args[:-3], b, gap, count, np.zeros((n, 3)), False, lam, nrm, hinge_scratch())
    e += contact_friction(x, x0, args[1], args[-4], gap, lam, nrm, friction, np.zeros((0, 3)), np.zeros(0), 0.01, b)
    return e + uzawa_energy(lam, nrm, x) + pair_energy(x, *damped)


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("friction", [0.0, 0.8])
def test_energy_matches_the_reference(seed, friction):
    x, y, args, lists, (d_i, d_j, dw), _ = _energy_case(seed)
    got = _energy(x, y, args, friction, (d_i, d_j, dw))
    want = naive_pd.energy(x, y, *lists, friction, [(i, j, w) for i, j, w in zip(d_i, d_j, dw) if w])
    assert got == pytest.approx(want, rel=1e-9)
    # with the hinges lagged the local step has no energy to give (its forces outside the matrix are old)
    n = x.shape[0]
    lagged = pd_rhs(x, y, *args[:-3], np.zeros((n, 3)), np.zeros((n, 3)), np.zeros(n), np.zeros((n, 3)), True,
                    *args[-3:-1], hinge_scratch())
    assert math.isnan(lagged)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_energy_is_the_potential_of_the_local_step(seed):
    """Without contacts the step's gradient ``A x - b(x)`` (the local step's ``b``, :func:`naive_pd.rhs`) is the
    energy's: central differences along seeded directions agree. Not the corner elements': their turn by half
    the excess is the nearest point of their band only when their arms are equally long, so they are left out
    (the line search takes their energy as it is)."""
    x, y, args, lists, damped, rng = _energy_case(seed, corners=False)
    mh2, inv_mass, dist, corners, springs, hinges = lists[:6]
    n = x.shape[0]
    free = inv_mass > 0
    no = np.zeros(n)
    # no contacts listed, no contact weight, no Uzawa forces
    args = args[:-6] + (np.zeros(0, I64), 0, no, np.zeros(n), np.zeros((n, 3)), args[-1])

    def e(p):
        return _energy(p, y, args, 0.0, damped)

    b, _ = naive_pd.rhs(x, y, mh2, inv_mass, no, dist, corners, springs, hinges, [], [], no, [], *lists[8:10],
                        no, np.zeros((n, 3)))
    lap = np.zeros((n, n))
    for i, j, w in [(i, j, w) for i, j, _, _, w in dist] + list(zip(*damped)):
        lap[[i, j], [i, j]] += w
        lap[i, j] -= w
        lap[j, i] -= w
    # A x - b, the damping's pull towards the start left out of y: b holds mh2 y, lap the damping's weight
    grad = np.diag(mh2) @ x + lap @ x - b
    for _ in range(3):
        v = rng.normal(size=x.shape) * free[:, None]
        h = 1e-7
        fd = (e(x + h * v) - e(x - h * v)) / (2 * h)
        assert fd == pytest.approx(float(np.sum(grad[free] * v[free])), rel=1e-4, abs=1e-9)


def _one_hinge():
    """Two 1 cm cotton triangles sharing an edge, three vertices pinned flat, the wing's tip free under gravity;
    and its analytic rest angle: ``k theta = m g r cos(theta)``."""
    pos = np.array([[0, 0, 0], [0, 0, 0.01], [-0.01, 0, 0.005], [0.01, 0, 0.005]], float)
    model = Model.from_polygons(np.array([0, 1, 2, 1, 0, 3]), np.array([0, 3, 6]), pos, "cotton",
                                pin_indices=[0, 1, 2])
    k, m, g, r = float(model.hinges.k[0]), float(model.mass[3]), 9.81, 0.01
    th = 0.5
    for _ in range(100):
        th -= (k * th - m * g * r * math.cos(th)) / (k + m * g * r * math.sin(th))
    return model, math.degrees(th)


def _wing_angle(history, dt, iterations=5):
    model, want = _one_hinge()
    solver = SolverPD(model, PDSettings(air_damping=20.0, shear_limit_deg=None, bend_limit=None,
                                        iterations=iterations, history=history))
    state = solver.init_state(dt)
    for _ in range(int(3 / dt)):
        solver.step(state, dt)
    p = state.pos
    return math.degrees(math.atan2(-p[3, 1], p[3, 0])), want, solver.max_speed(state)


@pytest.mark.parametrize("dt", [1 / 120, 1 / 2000])
def test_a_hinge_rests_at_its_analytic_angle(dt):
    """The wing's turn about the hinge is resisted by the hinge alone; the matrix's pair elements resist it as a
    stretch. With the quasi-Newton iterations the wing rests at its equilibrium at any step; the plain
    iterations rest where they undo each step's g h^2 (tens of degrees at 1/120 s)."""
    angle, want, speed = _wing_angle(5, dt)
    assert speed < 1e-6
    assert angle == pytest.approx(want, rel=1e-3)
    plain, _, _ = _wing_angle(0, dt)
    assert abs(plain - want) > 1.0


def test_history_is_validated():
    with pytest.raises(ValueError, match="history"):
        PDSettings(history=-1)
    with pytest.raises(ValueError, match="qn_move_limit"):
        PDSettings(history=5, qn_move_limit=0.0)


def test_a_step_from_pairs_that_no_longer_fit_falls_back_to_the_plain_one():
    """Pairs of another problem (seeded nonsense, positive curvature) give a direction the line search cannot
    take: the step drops them, takes the plain iteration, and the drape still reaches its rest."""
    model, want = _one_hinge()
    solver = SolverPD(model, PDSettings(air_damping=20.0, shear_limit_deg=None, bend_limit=None, iterations=5,
                                        history=3))
    dt = 1 / 120
    state = solver.init_state(dt)
    solver.step(state, dt)
    rng = np.random.default_rng(0)
    s = rng.normal(size=solver._qn_s.shape)
    solver._qn_s[:] = s
    solver._qn_t[:] = -s * 1e6  # the wrong sign: these pairs say the energy curves down
    solver._qn_rho[:] = 1.0
    solver._qn_at[:] = [2, 3]
    solver.step(state, dt)
    assert solver.qn_restarts >= 1
    for _ in range(360):
        solver.step(state, dt)
    p = state.pos
    assert math.degrees(math.atan2(-p[3, 1], p[3, 0])) == pytest.approx(want, rel=1e-3)


def test_quasi_newton_steps_are_deterministic():
    a = _wing_angle(5, 1 / 120, 4)
    b = _wing_angle(5, 1 / 120, 4)
    assert a == b


def test_compression_on_the_edges_leaves_the_bending_to_the_hinge():
    """A wing of 1/100 of cotton's bending hangs at 57.5 deg (its hinge against its weight). The bend spring across
    the hinge (1 % of the stretch stiffness) shortens as the wing turns and holds it at 16.5 deg; on the edges
    (``PDSettings.edge_compression``) the same share leaves the turn to the hinge."""
    import dataclasses

    from vfit_engine.sim.materials import COMPRESSION_SHARE, get_material

    mat = get_material("cotton")
    mat = dataclasses.replace(mat, bending_rigidity=tuple(b * 0.01 for b in mat.bending_rigidity))
    pos = np.array([[0, 0, 0], [0, 0, 0.01], [-0.01, 0, 0.005], [0.01, 0, 0.005]], float)
    model = Model.from_polygons(np.array([0, 1, 2, 1, 0, 3]), np.array([0, 3, 6]), pos, mat, pin_indices=[0, 1, 2])
    k, m, g, r = float(model.hinges.k[0]), float(model.mass[3]), 9.81, 0.01
    th = 0.5
    for _ in range(100):
        th -= (k * th - m * g * r * math.cos(th)) / (k + m * g * r * math.sin(th))
    angles = {}
    for on in (False, True):
        solver = SolverPD(model, PDSettings(air_damping=20.0, shear_limit_deg=None, bend_limit=None, iterations=5,
                                            history=5, edge_compression=on))
        state = solver.init_state(1 / 120)
        for _ in range(360):
            solver.step(state, 1 / 120)
        angles[on] = math.degrees(math.atan2(-state.pos[3, 1], state.pos[3, 0]))
        e_hi = solver._arrays[6]
        edges = np.isinf(e_hi)  # the compression springs: free when longer than at rest
        assert np.count_nonzero(edges) == (np.count_nonzero(model.spring_type == 0) if on else 0)
        if on:  # their full weights (the step's re-weighs those that do not act)
            np.testing.assert_allclose(solver._pairs["w"][:e_hi.size][edges],
                                       COMPRESSION_SHARE * model.spring_k[model.spring_type == 0])
    assert angles[True] == pytest.approx(math.degrees(th), rel=0.02)
    assert angles[False] < 0.5 * math.degrees(th)
