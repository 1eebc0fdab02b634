"""Cloth kernels against analytic cases and the slow references in naive_sim.py."""
import numpy as np
import pytest

import naive_sim
from vfit_engine.garment.springs import grid_polygons, vertex_spring_adjacency
from vfit_engine.kernels.collide_sphere import collide_spheres
from vfit_engine.kernels.integrate import integrate_verlet, substeps_parallel, substeps_serial
from vfit_engine.kernels.springs import eval_spring_forces, eval_spring_forces_gather
from vfit_engine.kernels.strain_limit import colour_springs, limit_strain


def _random_cloth(seed, n=40, s=120):
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(n, 3))
    xp = x + 0.01 * rng.normal(size=(n, 3))
    idx = rng.integers(0, n, size=(s, 2))
    idx = idx[idx[:, 0] != idx[:, 1]]
    idx = np.unique(np.sort(idx, axis=1), axis=0)
    m = idx.shape[0]
    rest = np.linalg.norm(x[idx[:, 1]] - x[idx[:, 0]], axis=1) * rng.uniform(0.7, 1.0, m)
    k = rng.uniform(1.0, 50.0, m)
    kd = rng.uniform(0.0, 0.5, m)
    inv_mass = rng.uniform(0.5, 2.0, n)
    inv_mass[rng.choice(n, 4, replace=False)] = 0.0
    return rng, x, xp, idx, rest, k, kd, inv_mass


def test_spring_pair_force_is_hooke_along_axis_and_sums_to_zero():
    x = np.array([[0.1, 0.2, -0.3], [0.9, 1.4, 0.3]])
    d = x[1] - x[0]
    length = np.linalg.norm(d)
    rest, k = np.array([1.0]), np.array([40.0])
    f = eval_spring_forces(x, x.copy(), 0.01, np.array([[0, 1]]), rest, k, np.array([3.0]))
    expected = k[0] * (length - rest[0]) * d / length
    np.testing.assert_allclose(f[0], expected, rtol=1e-14)
    np.testing.assert_allclose(f[0] + f[1], 0.0, atol=1e-14)
    assert np.linalg.norm(np.cross(f[0], d)) < 1e-13 * np.linalg.norm(f[0])
    # compressed: pushes apart; damping: opposes relative motion along the axis
    f = eval_spring_forces(x, x.copy(), 0.01, np.array([[0, 1]]), np.array([2 * length]), k, np.zeros(1))
    assert f[0] @ d < 0
    xp = x.copy()
    xp[1] -= 0.01 * d / length  # end 1 moving away at 1 m/s
    f = eval_spring_forces(x, xp, 0.01, np.array([[0, 1]]), np.array([length]), np.zeros(1), np.array([3.0]))
    np.testing.assert_allclose(f[0], 3.0 * d / length, rtol=1e-12)


@pytest.mark.parametrize("seed", [0, 1])
def test_spring_forces_match_reference(seed):
    _, x, xp, idx, rest, k, kd, _ = _random_cloth(seed)
    ref = naive_sim.spring_forces(x, xp, 0.005, idx, rest, k, kd)
    np.testing.assert_allclose(eval_spring_forces(x, xp, 0.005, idx, rest, k, kd), ref, rtol=1e-10, atol=1e-10)
    off, other, spring = vertex_spring_adjacency(x.shape[0], idx)
    got = eval_spring_forces_gather(x, xp, 0.005, off, other, rest[spring], k[spring], kd[spring])
    np.testing.assert_allclose(got, ref, rtol=1e-10, atol=1e-10)


def test_integrate_matches_reference():
    rng, x, xp, _, _, _, _, inv_mass = _random_cloth(2)
    f = rng.normal(size=x.shape)
    g = np.array([0.0, -9.81, 0.0])
    got = integrate_verlet(x, xp, inv_mass, f, g, 0.004, 0.01)
    np.testing.assert_allclose(got, naive_sim.integrate(x, xp, inv_mass, f, g, 0.004, 0.01), rtol=1e-14, atol=1e-15)
    assert np.array_equal(got[inv_mass == 0], x[inv_mass == 0])


@pytest.mark.parametrize("omega", [1.0, 1.5])
def test_strain_limit_one_sweep_matches_reference(omega):
    _, x, _, idx, rest, _, _, inv_mass = _random_cloth(3)
    max_len = 1.1 * rest
    got = x.copy()
    limit_strain(got, inv_mass, idx, max_len, iterations=1, omega=omega)
    ref = naive_sim.strain_limit_sweep(x, inv_mass, idx, max_len, omega)
    np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-12)
    assert not np.array_equal(got, x)
    pinned = inv_mass == 0
    assert np.array_equal(got[pinned], x[pinned])


def test_strain_limiting_brings_stretched_chain_within_limit():
    n = 12
    x = np.zeros((n, 3))
    x[:, 1] = -np.linspace(0, 1.0, n) ** 1.5 * 2.0  # irregular, up to ~ 3x stretched
    idx = np.stack([np.arange(n - 1), np.arange(1, n)], axis=1)
    rest = np.full(n - 1, 1.0 / (n - 1))
    inv_mass = np.ones(n)
    inv_mass[0] = 0.0  # hanging from a pin
    before = np.linalg.norm(np.diff(x, axis=0), axis=1) / rest - 1
    assert before.max() > 1.0
    # equal-split Gauss-Seidel converges slowly (O(n^2) sweeps) but surely
    limit_strain(x, inv_mass, idx, 1.1 * rest, iterations=1500)
    after = np.linalg.norm(np.diff(x, axis=0), axis=1) / rest - 1
    assert after.max() <= 0.10 + 1e-8
    assert np.array_equal(x[0], np.zeros(3))


def test_colouring_is_a_proper_edge_colouring():
    pos, fv, fo = grid_polygons(7, 5)
    from vfit_engine.garment.springs import build_springs
    idx = build_springs(fv, fo, pos).indices
    order, off = colour_springs(idx, pos.shape[0])
    assert np.array_equal(np.sort(order), np.arange(idx.shape[0]))
    for c in range(off.size - 1):
        verts = idx[order[off[c]:off[c + 1]]].ravel()
        assert np.unique(verts).size == verts.size


SPHERE_TABLE = [
    # (point, expected position after projection) for a unit sphere at the origin, skin 0.01
    ((0.0, 2.0, 0.0), (0.0, 2.0, 0.0)),          # outside: untouched
    ((0.0, 1.02, 0.0), (0.0, 1.02, 0.0)),        # outside the skin
    ((1.0, 0.0, 0.0), (1.01, 0.0, 0.0)),         # touching the true surface: lifted to the skin
    ((0.0, 0.0, -0.5), (0.0, 0.0, -1.01)),       # inside: out along the centre direction
    ((0.3, 0.4, 0.0), (0.606, 0.808, 0.0)),      # inside, off axis (3-4-5)
    ((0.0, 0.0, 0.0), (0.0, 1.01, 0.0)),         # at the centre: +Y by convention
]


@pytest.mark.parametrize("point, expected", SPHERE_TABLE)
def test_point_vs_sphere_table(point, expected):
    from vfit_engine.collide.spheres import SphereCollider

    sph = SphereCollider([[0.0, 0.0, 0.0]], [1.0], skin=0.01, friction=0.0, restitution=0.0)
    x = np.array([point], dtype=np.float64)
    xp = x.copy()
    sph.project(x, xp, np.ones(1))
    np.testing.assert_allclose(x[0], expected, atol=1e-14)
    pinned = np.array([point], dtype=np.float64)
    sph.project(pinned, pinned.copy(), np.zeros(1))
    assert np.array_equal(pinned[0], point)


def test_sphere_friction_and_restitution():
    c, r = np.zeros((1, 3)), np.ones(1)
    x = np.array([[0.0, 0.9, 0.0]])
    xp = np.array([[-0.2, 1.2, 0.0]])  # moved +0.2 tangential, -0.3 normal
    collide_spheres(x, xp, np.ones(1), c, r, np.array([0.25]), np.array([0.5]))
    np.testing.assert_allclose(x[0], [0.0, 1.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(x[0] - xp[0], [0.75 * 0.2, 0.5 * 0.3, 0.0], atol=1e-15)


def test_sphere_collide_matches_reference():
    rng = np.random.default_rng(4)
    n = 200
    x = rng.uniform(-1.0, 1.0, size=(n, 3))
    xp = x + 0.05 * rng.normal(size=(n, 3))
    inv_mass = np.ones(n)
    inv_mass[:10] = 0.0
    centres = rng.uniform(-0.5, 0.5, size=(3, 3))
    radii = rng.uniform(0.3, 0.8, 3)
    fr, rs = rng.uniform(0, 1, 3), rng.uniform(0, 1, 3)
    ref_x, ref_xp = naive_sim.collide_spheres(x, xp, inv_mass, centres, radii, fr, rs)
    got_x, got_xp = x.copy(), xp.copy()
    collide_spheres(got_x, got_xp, inv_mass, centres, radii, fr, rs)
    np.testing.assert_allclose(got_x, ref_x, rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(got_xp, ref_xp, rtol=1e-13, atol=1e-13)
    assert np.sum(np.any(got_x != x, axis=1)) > 10


@pytest.mark.parametrize("gather, parallel", [(False, False), (True, False), (True, True)])
def test_fused_substeps_match_reference(gather, parallel):
    rng, x, xp, idx, rest, k, kd, inv_mass = _random_cloth(5)
    order, colour_off = colour_springs(idx[::2], x.shape[0])
    if not parallel:
        order, colour_off = np.arange(order.size), np.array([0, order.size])
    lim_idx = idx[::2][order]
    lim_len = 1.05 * rest[::2][order]
    off, other, spring = vertex_spring_adjacency(x.shape[0], idx)
    centres, radii = np.array([[0.0, 0.0, 0.0]]), np.array([0.8])
    fr, rs = np.array([0.3]), np.array([0.2])
    g = np.array([0.0, -9.81, 0.0])
    dt, c_air, iters, omega, n_sub = 0.002, 0.01, 3, 1.2, 4
    ref_x, ref_xp = x.copy(), xp.copy()
    for _ in range(n_sub):
        ref_x, ref_xp = naive_sim.substep(ref_x, ref_xp, inv_mass, g, idx, rest, k, kd, lim_idx, lim_len, iters,
                                          omega, centres, radii, fr, rs, dt, c_air)
    got_x, got_xp = x.copy(), xp.copy()
    kernel = substeps_parallel if parallel else substeps_serial
    kernel(got_x, got_xp, inv_mass, g, gather, idx[:, 0].copy(), idx[:, 1].copy(), rest, k, kd,
                    off, other, rest[spring], k[spring], kd[spring], lim_idx[:, 0].copy(), lim_idx[:, 1].copy(),
                    lim_len, colour_off, iters, omega, centres, radii, fr, rs,
                    np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros((0, 3)), dt, c_air, 0, n_sub, n_sub,
                    np.zeros_like(x), np.zeros_like(x))
    np.testing.assert_allclose(got_x, ref_x, rtol=1e-9, atol=1e-11)
    np.testing.assert_allclose(got_xp, ref_xp, rtol=1e-9, atol=1e-11)
