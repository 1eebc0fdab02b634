"""Bending hinges: the kernels (forces, constraints) against NumPy references, the energy of a bent sheet
against B kappa^2 / 2, the moment of a bent strip against B kappa, and the step the solver takes with them."""
import math

import naive_sim
import numpy as np
import pytest

from vfit_engine.sim.springs import grid_polygons
from vfit_engine.kernels.bending import (HINGE_BLOCK, add_elastic_hinge_forces, atan2_select, hinge_scratch,
                                         eval_hinge_forces, project_hinges)
from vfit_engine.sim.bending import bending_energy, build_hinges, hinge_angles
from vfit_engine.textile.specimen import disc


def _cylinder(pos, kappa, phi):
    """The flat sheet ``pos`` (x-z plane) rolled isometrically into a cylinder of curvature ``kappa``, its
    axis at ``phi`` to z."""
    u = math.cos(phi) * pos[:, 0] + math.sin(phi) * pos[:, 2]
    v = -math.sin(phi) * pos[:, 0] + math.cos(phi) * pos[:, 2]
    a = u * kappa
    return np.stack([np.sin(a) / kappa, (1 - np.cos(a)) / kappa, v], axis=1)


def test_kernel_matches_the_reference_on_random_hinges():
    rng = np.random.default_rng(7)
    pos, fv, fo = grid_polygons(5, 4, 0.04, 0.03, quads=False)
    h = build_hinges(fv, fo, pos, 5e-6, damping=0.01)
    x = pos + rng.normal(0, 2e-3, pos.shape)
    xp = x - rng.normal(0, 1e-4, pos.shape)
    dt = 1e-3
    rest = rng.uniform(-0.5, 0.5, h.count)
    k, kd = rng.uniform(1e-6, 1e-5, h.count), rng.uniform(0, 1e-7, h.count)
    got = eval_hinge_forces(x, xp, dt, h.indices, k, kd, rest)
    want = naive_sim.hinge_forces(x, xp, dt, h.indices, k, kd, rest)
    np.testing.assert_allclose(got, want, atol=1e-9 * np.abs(want).max(), rtol=1e-5)
    # internal forces: no net force, no net torque
    np.testing.assert_allclose(got.sum(axis=0), 0.0, atol=1e-12)
    np.testing.assert_allclose(np.cross(x, got).sum(axis=0), 0.0, atol=1e-12)


def test_elastic_hinge_forces_are_the_undamped_hinge_forces():
    """The projective-dynamics kernel (blocks of hinges, a branch-free angle) against the explicit one without
    damping and the reference, over several blocks, a range that starts and ends inside blocks, and a collapsed
    triangle (no force)."""
    rng = np.random.default_rng(5)
    pos, fv, fo = grid_polygons(12, 9, 0.2, 0.15, quads=False)
    h = build_hinges(fv, fo, pos, 5e-6)
    assert h.count > 2 * HINGE_BLOCK
    x = pos + rng.normal(0, 4e-3, pos.shape)
    rest = rng.uniform(-3.0, 3.0, h.count)  # some bends wrap past pi
    k = rng.uniform(1e-6, 1e-5, h.count)
    idx = np.ascontiguousarray(h.indices, dtype=np.int64)
    h0, h1 = 3, h.count - 5
    got = np.zeros_like(x)
    add_elastic_hinge_forces(x, idx, k, rest, got, h0, h1, hinge_scratch())
    want = eval_hinge_forces(x, x, 1.0, idx[h0:h1], k[h0:h1], np.zeros(h1 - h0), rest[h0:h1])
    # the same operations but the angle's (within 2 ulp of math.atan2): equal to the rounding
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-14 * np.abs(want).max())
    ref = naive_sim.hinge_forces(x, x, 1.0, idx[h0:h1], k[h0:h1], np.zeros(h1 - h0), rest[h0:h1])
    np.testing.assert_allclose(got, ref, atol=1e-9 * np.abs(ref).max(), rtol=1e-5)
    x[idx[3, 2]] = x[idx[3, 0]]  # hinge 3's first triangle collapsed: no normal
    alone = np.zeros_like(x)
    add_elastic_hinge_forces(x, idx, k, rest, alone, 3, 4, hinge_scratch())
    assert np.all(alone == 0.0)
    add_elastic_hinge_forces(x, idx, k, rest, alone, 4, 5, hinge_scratch())
    assert np.any(alone != 0.0)


@pytest.mark.parametrize("scale", [1e-12, 1.0, 1e12])
def test_atan2_select_is_atan2_within_2_ulp(scale):
    rng = np.random.default_rng(9)
    y, x = rng.normal(size=(2, 20000)) * scale
    y[:50] = 0.0
    x[50:100] = 0.0
    y[100:200] = x[100:200] * rng.uniform(0.6599, 0.6601, 100)  # where the reduction switches
    y[200:300] = -x[200:300]
    got = np.array([atan2_select(a, b) for a, b in zip(y, x)])
    want = np.arctan2(y, x)
    assert np.all(np.abs(got - want) <= 2 * np.spacing(np.abs(want)))
    assert atan2_select(0.0, 0.0) == 0.0 and atan2_select(-0.0, -1.0) == math.pi


def test_constraint_kernel_matches_the_reference_on_random_hinges():
    rng = np.random.default_rng(11)
    pos, fv, fo = grid_polygons(5, 4, 0.04, 0.03, quads=False)
    h = build_hinges(fv, fo, pos, 5e-6)
    x = np.ascontiguousarray(pos + rng.normal(0, 2e-3, pos.shape))
    w = rng.uniform(50, 200, pos.shape[0])
    rest = rng.uniform(-0.5, 0.5, h.count)
    compliance = np.where(rng.random(h.count) < 0.8, 1.0 / rng.uniform(1e-6, 1e-4, h.count), 0.0)
    lam0 = rng.normal(0, 1e-8, h.count)
    want, want_lam = naive_sim.hinge_sweep(x, w, h.indices, compliance, rest, lam0, 1.0 / 2e-3 ** 2)
    lam = lam0.copy()
    project_hinges(x, w, h.indices, compliance, rest, lam, 2e-3)
    np.testing.assert_allclose(x, want, atol=1e-9)
    np.testing.assert_allclose(lam, want_lam, rtol=1e-5, atol=1e-15)
    assert np.all(lam[compliance == 0] == lam0[compliance == 0]) and np.any(lam != lam0)


def test_stiff_hinges_as_constraints_keep_the_fabric_s_bending_beyond_the_explicit_step():
    # the cantilever at 4x the largest explicit step: solved as constraints the hinges droop the strip as the
    # explicit step does; softened to the step's bound (the earlier solver) it hangs nearly straight down
    from vfit_engine.sim.materials import PRESETS
    from vfit_engine.textile.cantilever import droop, peirce_overhang

    silk = PRESETS["silk"]
    overhang = peirce_overhang(silk.bending_length)
    explicit, info = droop(silk, overhang, 0.005)
    assert info["implicit_hinges"] == 0.0 and info["softened_hinges"] == 0.0
    implicit, info4 = droop(silk, overhang, 0.005, dt=4 * info["dt_s"])
    assert info4["implicit_hinges"] > 0.5 and info4["softened_hinges"] == 0.0 and info4["settled"]
    assert implicit == pytest.approx(explicit, abs=1.0)
    softened, info_s = droop(silk, overhang, 0.005, dt=4 * info["dt_s"], implicit_hinges=False)
    assert info_s["softened_hinges"] > 0.5 and softened > explicit + 30.0


@pytest.mark.parametrize("mesh", ["disc", "quads"])
def test_a_rolled_sheet_stores_B_kappa_squared_over_two(mesh):
    b, kappa = 7e-6, 12.0
    if mesh == "disc":
        pos, fv, fo = disc(0.1, 0.005)
        directions = np.radians([0, 20, 45, 70, 90, 135])
    else:
        pos, fv, fo = grid_polygons(41, 41, 0.2, 0.2, quads=True)
        directions = np.radians([0, 90])  # along its grid lines (diagonal bends are stiffer: module docstring)
    h = build_hinges(fv, fo, pos, b)
    inner = np.all(np.hypot(pos[h.indices, 0], pos[h.indices, 2]) < 0.06, axis=1)
    # the area each hinge stands for: a third of its two triangles' (k = B |e|^2 / (A0 + A1) undone)
    x0, x1, x2, x3 = (pos[h.indices[:, m]] for m in range(4))
    tri_area = 0.5 * (np.linalg.norm(np.cross(x1 - x0, x2 - x0), axis=1)
                      + np.linalg.norm(np.cross(x1 - x0, x3 - x0), axis=1))
    weight = h.k * tri_area / (b * np.sum((x1 - x0) ** 2, axis=1))  # 1, or 1/2 for each of a quad's splits
    area = np.sum((weight * tri_area / 3.0)[inner])
    for phi in directions:
        theta = hinge_angles(h.indices, _cylinder(pos, kappa, phi))
        energy = 0.5 * np.sum((h.k * theta ** 2)[inner])
        assert energy / (0.5 * b * kappa ** 2 * area) == pytest.approx(1.0, abs=0.06), np.degrees(phi)


def test_a_bent_strip_carries_the_moment_B_kappa():
    """M = dE/dkappa / (length x width) on a strip rolled to curvature kappa, from its energy (the hinges'
    moments summed): B kappa within the mesh's error."""
    b = 20e-6
    pos, fv, fo = grid_polygons(61, 11, 0.3, 0.05, quads=True)
    h = build_hinges(fv, fo, pos, b)
    for kappa in (2.0, 10.0, 30.0):
        dk = 1e-3 * kappa
        de = bending_energy(h, _cylinder(pos, kappa + dk, 0.0)) - bending_energy(h, _cylinder(pos, kappa - dk, 0.0))
        moment = de / (2 * dk) / (0.3 * 0.05)
        assert moment == pytest.approx(b * kappa, rel=0.06)


def test_warp_and_weft_follow_pattern_uvs():
    pos, fv, fo = grid_polygons(11, 11, 0.1, 0.1, quads=True)
    uvs = pos[:, [0, 2]] * 5.0  # a flat pattern laid out at one scale
    iso = build_hinges(fv, fo, pos, (10e-6, 2e-6))
    aniso = build_hinges(fv, fo, pos, (10e-6, 2e-6), uvs=uvs, face_uvs=fv)
    assert not iso.anisotropic and aniso.anisotropic
    bend_u = hinge_angles(aniso.indices, _cylinder(pos, 10.0, 0.0))  # curved along x = U: across the weft
    bend_v = hinge_angles(aniso.indices, _cylinder(pos, 10.0, math.pi / 2))  # along z = V, the warp
    e_u, e_v = np.sum(aniso.k * bend_u ** 2), np.sum(aniso.k * bend_v ** 2)
    assert e_v / e_u == pytest.approx(5.0, rel=0.05)
    # UVs that are a texture atlas (one island scaled 3x) leave the cloth isotropic, with the mean rigidity
    atlas = uvs.copy()
    atlas[pos[:, 0] > 0] *= 3.0
    assert not build_hinges(fv, fo, pos, (10e-6, 2e-6), uvs=atlas, face_uvs=fv).anisotropic
    np.testing.assert_allclose(iso.k.sum(), build_hinges(fv, fo, pos, 6e-6).k.sum())


def test_a_garment_s_own_folds_are_its_rest_and_slivers_carry_no_hinge():
    pos, fv, fo = grid_polygons(3, 2, 0.02, 0.01, quads=False)
    folded = pos.copy()
    folded[2::3, 1] = 0.004  # one column lifted: the sheet bent along a line
    h = build_hinges(fv, fo, folded, 1e-5)
    np.testing.assert_allclose(bending_energy(h, folded), 0.0, atol=1e-18)
    assert bending_energy(h, pos) > 0
    sliver = np.array([[0, 0, 0], [1, 0, 0], [0.5, 0, 1e-6], [0.5, 0, 1.0]], float)
    assert build_hinges(np.array([0, 1, 2, 1, 0, 3]), np.array([0, 3, 6]), sliver, 1e-5).count == 0


def test_the_solver_step_holds_the_hinges_stiffness():
    from vfit_engine.sim.model import Model
    from vfit_engine.sim.solver_settings import VerletSettings
    from vfit_engine.sim.solver_verlet import SolverVerlet

    pos, fv, fo = disc(0.05, 0.005)
    model = Model.from_polygons(fv, fo, pos, "denim")
    solver = SolverVerlet(model)
    dt = solver.max_stable_dt()
    _, _, hk, _, alpha = solver.effective_constants(dt)
    assert solver.stiff_hinges == 0.0 and solver.bending_kept == 1.0 and not alpha.any()
    np.testing.assert_array_equal(hk, model.hinges.k)
    # beyond the explicit bound the stiff hinges become constraints with the material's stiffness
    _, _, hk, _, alpha = solver.effective_constants(4 * dt)
    stiff = alpha > 0
    assert solver.implicit_hinges == solver.stiff_hinges == pytest.approx(stiff.mean()) and stiff.any()
    np.testing.assert_allclose(1.0 / alpha[stiff], model.hinges.k[stiff])
    assert not hk[stiff].any() and solver.softened_hinges == 0.0 and solver.bending_kept == 1.0
    # round an opening the body forces wider they stay explicit, softened; the report's share says so
    solver.allow_stretch(np.arange(model.particle_count // 2), 0.1)
    _, _, hk, _, alpha = solver.effective_constants(4 * dt)
    assert 0.0 < solver.softened_hinges < solver.stiff_hinges and solver.bending_kept < 1.0
    kept = np.where(alpha > 0, model.hinges.k, hk)
    assert solver.bending_kept == pytest.approx(kept.sum() / model.hinges.k.sum())
    # without implicit hinges every stiff hinge is softened (the earlier solver)
    soft = SolverVerlet(model, VerletSettings(implicit_hinges=False))
    _, _, hk, _, alpha = soft.effective_constants(4 * dt)
    assert not alpha.any() and soft.softened_hinges == soft.stiff_hinges > 0.0
    assert soft.bending_kept == pytest.approx(hk.sum() / model.hinges.k.sum()) and soft.bending_kept < 1.0


def test_gradient_norms_match_finite_differences():
    from vfit_engine.sim.bending import hinge_gradient_norms

    rng = np.random.default_rng(3)
    pos, fv, fo = grid_polygons(4, 3, 0.03, 0.02, quads=False)
    x = pos + rng.normal(0, 2e-3, pos.shape)
    h = build_hinges(fv, fo, pos, 1e-5)
    got = hinge_gradient_norms(h.indices, x)
    eps = 1e-7
    for k in range(h.count):
        ids = h.indices[k:k + 1]
        for m in range(4):
            g = np.zeros(3)
            for c in range(3):
                p, q = x.copy(), x.copy()
                p[ids[0, m], c] += eps
                q[ids[0, m], c] -= eps
                g[c] = (hinge_angles(ids, p)[0] - hinge_angles(ids, q)[0]) / (2 * eps)
            assert got[k, m] == pytest.approx(np.linalg.norm(g), rel=1e-5)
