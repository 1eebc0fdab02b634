"""Sewing (SolverPD.sew / close_seams / weigh, the frame loop's sewing, drape.sew): seams close and conserve
momentum, a seam's allowed length holds, gravity can be switched off, and a shared pattern sews on the body."""
from pathlib import Path

import numpy as np
import pytest

from vfit_engine.sim.model import Model
from vfit_engine.sim.solver_pd import SolverPD
from vfit_engine.sim.solver_settings import PDSettings
from vfit_engine.sim.springs import grid_polygons

PATTERNS = Path(__file__).resolve().parents[2] / "shared" / "assets" / "patterns"
needs_shared = pytest.mark.skipif(not PATTERNS.is_dir(), reason="../shared/assets/patterns absent")


def _two_sheets(gap=0.1):
    """Two 10 x 10 cm cotton sheets in the plane y = 0, side by side ``gap`` apart along x, and the seam pairs of
    their facing edges (left sheet's right edge to the right sheet's left edge, row by row)."""
    pos, fv, fo = grid_polygons(5, 5, 0.1, 0.1)
    n = pos.shape[0]
    right = pos + [0.1 + gap, 0.0, 0.0]
    both = np.concatenate([pos, right])
    faces = np.concatenate([fv, fv + n])
    offsets = np.concatenate([fo, fo[1:] + fv.size])
    model = Model.from_polygons(faces, offsets, both, "cotton")
    a = np.flatnonzero(np.isclose(pos[:, 0], pos[:, 0].max()))
    b = n + np.flatnonzero(np.isclose(pos[:, 0], pos[:, 0].min()))
    a, b = a[np.argsort(pos[a, 2])], b[np.argsort(pos[b - n, 2])]
    return model, both, np.stack([a, b], axis=1)


def _run(solver, state, steps, dt=1 / 120):
    for _ in range(steps):
        solver.step(state, dt)
    return state


def test_a_seam_closes_and_keeps_the_centre_of_mass():
    """Seams are internal forces: the sheets meet where their centre of mass was, and nothing else moves it."""
    model, pos, pairs = _two_sheets()
    solver = SolverPD(model, PDSettings(gravity=(0.0, 0.0, 0.0)))
    solver.sew(pairs)
    state = _run(solver, solver.init_state(1 / 120), 240)
    gap = np.linalg.norm(state.pos[pairs[:, 0]] - state.pos[pairs[:, 1]], axis=1)
    assert gap.max() < 1e-3
    m = model.mass[:, None]
    np.testing.assert_allclose((m * state.pos).sum(0) / m.sum(), (m * pos).sum(0) / m.sum(), atol=1e-9)
    # the sheets themselves are not stretched by their sewing
    assert model.max_stretch(state.pos) < 0.01


def test_close_seams_lets_a_seam_be_no_longer_than_its_length_then_shuts_it():
    model, pos, pairs = _two_sheets()
    solver = SolverPD(model, PDSettings(gravity=(0.0, 0.0, 0.0)))
    solver.sew(pairs, length=0.105)
    state = solver.init_state(1 / 120)
    _run(solver, state, 60)  # free within their length: nothing pulls
    gap = np.linalg.norm(state.pos[pairs[:, 0]] - state.pos[pairs[:, 1]], axis=1)
    np.testing.assert_allclose(gap, 0.1, atol=1e-9)
    solver.close_seams(0.04)  # shorter than the gap: the seams pull the sheets to within 4 cm
    _run(solver, state, 240)
    gap = np.linalg.norm(state.pos[pairs[:, 0]] - state.pos[pairs[:, 1]], axis=1)
    assert gap.max() < 0.04 * 1.02
    solver.close_seams(0.0)
    _run(solver, state, 240)
    gap = np.linalg.norm(state.pos[pairs[:, 0]] - state.pos[pairs[:, 1]], axis=1)
    assert gap.max() < 1e-3


def test_weigh_switches_gravity():
    model, pos, _ = _two_sheets()
    solver = SolverPD(model, PDSettings(air_damping=0.0))
    state = solver.init_state(1 / 120)
    solver.weigh(0.0)
    state.pos_prev[:] = state.pos  # at rest: no fall was started by init_state's gravity
    _run(solver, state, 60)
    np.testing.assert_allclose(state.pos, pos, atol=1e-12)
    solver.weigh(1.0)
    _run(solver, state, 60)
    assert state.pos[:, 1].mean() < -0.1  # half a second of free fall: g t^2 / 2 = 1.2 m


def test_bad_seams_are_refused():
    model, _, pairs = _two_sheets()
    solver = SolverPD(model)
    with pytest.raises(ValueError):
        solver.sew([[0, 0]])
    with pytest.raises(ValueError):
        solver.sew([[0, model.particle_count]])
    with pytest.raises(ValueError):
        solver.sew(pairs, length=-1.0)


@pytest.fixture(scope="module")
def skirt_setup():
    """The shared four-panel skirt set up to be sewn on the default female body (the sewing itself is draped in
    tests/test_cli_pattern.py, through the CLI)."""
    from vfit_engine.body.model import BodyModel
    from vfit_engine.body.resolve import default_body
    from vfit_engine.drape.settings import DrapeSettings, projective
    from vfit_engine.drape.sew import prepare_pattern_drape
    from vfit_engine.pattern.load import load

    model = BodyModel.load()
    body = default_body(model, "female")
    pattern, _ = load(PATTERNS / "gpg_skirt_4_panels.json")
    return pattern, prepare_pattern_drape(pattern, body, model, settings=projective(DrapeSettings()))


@needs_shared
def test_a_pattern_is_set_up_with_the_flat_pattern_as_its_rest(skirt_setup):
    from vfit_engine.pattern.mesh import mesh_pattern

    pattern, setup = skirt_setup
    cloth = mesh_pattern(pattern)
    # the rest shape is the flat pattern: every panel as cut (its UVs), flat (z = 0), the panels apart
    assert np.all(setup.rest[:, 2] == 0.0)
    for k in range(len(cloth.panel_names)):
        sel = np.flatnonzero(cloth.vertex_panel == k)
        np.testing.assert_allclose(setup.rest[sel, :2] - setup.rest[sel[0], :2], cloth.uv[sel] - cloth.uv[sel[0]],
                                   atol=1e-12)
    assert [g for g, _ in setup.garment.mesh.groups] == list(cloth.panel_names)
    # the seams are the mesh's pairs less a dart's tip sewn to itself; no pins (the seams and the body hold it)
    assert len(setup.seams) == int(np.count_nonzero(cloth.seam_pairs[:, 0] != cloth.seam_pairs[:, 1]))
    assert setup.pins.indices.size == 0
    # the start: every panel placed off the body
    d, _, _, _ = setup.collider.query(setup.start, max_out=0.05, max_in=np.inf)
    assert d.min() > 0.0


@needs_shared
def test_sewing_needs_the_projective_solver(skirt_setup):
    from vfit_engine.drape.loop import build_solver
    from vfit_engine.drape.settings import DrapeSettings

    _, setup = skirt_setup
    with pytest.raises(ValueError, match="projective"):
        build_solver(setup, DrapeSettings())
