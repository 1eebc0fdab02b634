"""The projective-dynamics solver under a moving body (SolverPD.body_moved, the animate loop on it): a sheet on a
moving slab carried at the slab's speed by friction, a body gone from under the cloth leaving no ghost of it, a
sphere moving into a sheet pushing it without penetration, the matrix untouched by the body's motion, the
animation's figures on both solvers, determinism; and ``vfit animate PATTERN``."""
import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from vfit_cli.main import cli

PATTERNS = Path(__file__).resolve().parents[2] / "shared" / "assets" / "patterns"
SKIRT = PATTERNS / "gpg_skirt_4_panels.json"
needs_shared = pytest.mark.skipif(not PATTERNS.is_dir(), reason="../shared/assets/patterns absent")


def _moving(verts, tris, step, frames, cell):
    """A collider of ``verts`` moving by ``step`` (3,) m a frame for ``frames`` frames."""
    from vfit_engine.collide.moving_body import MovingBodyCollider

    end = verts + np.asarray(step) * frames
    return MovingBodyCollider(verts, tris, box=(np.minimum(verts, end).min(axis=0), np.maximum(verts, end).max(axis=0)),
                              cell=cell)


def _drive(solver, state, col, verts, step, frames, fps, steps, velocity, each=None):
    """Move the body ``frames`` frames as the animate loop does (vfit_engine.animate.loop._simulate_frame): a grid
    per frame, the body put where it is before each of the frame's ``steps`` steps, its velocity given."""
    dt = 1.0 / (fps * steps)
    for k in range(1, frames + 1):
        col.advance(verts + np.asarray(step) * k)
        for j in range(steps):
            col.at((j + 1) / steps)
            solver.body_moved(col.motion_bound, velocity=velocity)
            solver.step_frame(state, dt, substeps=1)
        if each is not None:
            each(k)


def test_a_sheet_on_a_moving_slab_is_carried_at_its_speed():
    """A sheet resting on a slab that sets off sideways at 0.3 m/s: Coulomb friction (mu = 0.5) takes it up to the
    slab's speed, slipping v^2 / (2 mu g) = 9.2 mm while it does (analytic), then it rides along: after 0.5 s it
    moves at the slab's speed and lies v t - 9.2 mm on, the same to the byte run again. Told the body is still
    (no velocity), the contacts hold it back where it lay instead."""
    import trimesh

    from vfit_engine.sim.contact_points import contact_points
    from vfit_engine.sim.model import Model
    from vfit_engine.sim.solver_pd import SolverPD
    from vfit_engine.sim.solver_settings import ContactSettings, PDSettings
    from vfit_engine.sim.springs import grid_polygons

    speed, fps, frames, mu = 0.3, 30, 15, 0.5
    slab = trimesh.creation.box(extents=(0.6, 0.1, 0.6))
    v0, tris = np.ascontiguousarray(slab.vertices, dtype=np.float64), np.ascontiguousarray(slab.faces)
    pos, fv, fo = grid_polygons(6, 6, 0.2, 0.2)
    start = np.ascontiguousarray(pos + [0.0, 0.05 + 0.0021, 0.0])  # on the top face, at the skin (2 mm)
    model = Model.from_polygons(fv, fo, pos, "cotton")
    moved, speed_end, end = {}, {}, []
    for carried in (True, True, False):  # twice carried: the same bytes (determinism)
        col = _moving(v0, tris, (speed / fps, 0.0, 0.0), frames, 0.02)
        solver = SolverPD(model, PDSettings(), ContactSettings(skin=0.002, friction=mu), body=col,
                          points=contact_points(fv, fo, pos, spacing=0.015))
        state = solver.init_state(1 / 120, pos=start)
        last = {}
        _drive(solver, state, col, v0, (speed / fps, 0.0, 0.0), frames, fps, 4,
               np.tile([speed if carried else 0.0, 0.0, 0.0], (len(v0), 1)),
               each=lambda k: last.update({k: state.pos[:, 0].mean()}))
        end.append(state.pos.tobytes())
        moved[carried] = last[frames] - start[:, 0].mean()
        speed_end[carried] = (last[frames] - last[frames - 1]) * fps  # over the last frame
        if carried:  # on the slab (a loose sheet rucks up a few mm on PD's contacts, the same on a still slab)
            lift = state.pos[:, 1] - start[:, 1]
            assert lift.min() > -0.0005 and lift.max() < 0.01
    slip = speed ** 2 / (2 * mu * 9.81)
    assert speed_end[True] == pytest.approx(speed, rel=0.02)
    assert moved[True] == pytest.approx(speed * frames / fps - slip, abs=0.003)
    assert abs(moved[False]) < 0.005 and abs(speed_end[False]) < 0.01
    assert end[0] == end[1] != end[2]


def test_a_body_gone_from_under_the_cloth_leaves_no_ghost_holding_it():
    """A sheet resting on a slab that then leaves sideways at 7.5 m/s (25 cm a 1/120 s step, out from under it
    within two steps) and stops there: the sheet falls under gravity where the slab was (below its top by more
    than half the free fall's g t^2 / 2 after 0.3 s, air damping and all). Its vertices carried contact forces when
    they lost their contact points; on a moving body they let go at once (``contact_forces``' ``release``): kept,
    each one's plane -- where the skin was -- held the sheet up like a ghost of the slab."""
    import trimesh

    from vfit_engine.sim.contact_points import contact_points
    from vfit_engine.sim.model import Model
    from vfit_engine.sim.solver_pd import SolverPD
    from vfit_engine.sim.solver_settings import ContactSettings, PDSettings
    from vfit_engine.sim.springs import grid_polygons

    slab = trimesh.creation.box(extents=(0.6, 0.1, 0.6))
    v0, tris = np.ascontiguousarray(slab.vertices, dtype=np.float64), np.ascontiguousarray(slab.faces)
    pos, fv, fo = grid_polygons(6, 6, 0.2, 0.2)
    start = np.ascontiguousarray(pos + [0.0, 0.05 + 0.0021, 0.0])  # on the top face, at the skin (2 mm)
    model = Model.from_polygons(fv, fo, pos, "cotton")
    away = np.array([1.0, 0.0, 0.0])
    col = _moving(v0, tris, away, 1, 0.02)
    solver = SolverPD(model, PDSettings(), ContactSettings(skin=0.002, friction=0.0), body=col,
                      points=contact_points(fv, fo, pos, spacing=0.015))
    state = solver.init_state(1 / 120, pos=start)
    still = np.zeros((len(v0), 3))
    _drive(solver, state, col, v0, np.zeros(3), 5, 30, 4, still)  # resting on it
    assert abs(state.pos[:, 1].mean() - start[:, 1].mean()) < 0.002
    _drive(solver, state, col, v0, away, 1, 30, 4, np.tile(away * 30, (len(v0), 1)))  # gone
    _drive(solver, state, col, v0 + away, np.zeros(3), 9, 30, 4, still)  # and stays away
    t = 10 / 30
    assert state.pos[:, 1].mean() < start[:, 1].mean() - 0.5 * 9.81 * t * t / 2


def test_a_sphere_moving_into_a_sheet_pushes_it_without_penetration():
    """A sphere rising into a sheet at 1.2 m/s (4 cm a 1/30 s frame, a walking shin's speed) for 6 frames: the
    sheet's surface is never in it (no sample inside, at any frame's end), its top rides up with the sphere's, and
    the matrix is not refactored for it (a constant matrix stays constant under a moving body)."""
    import trimesh

    from vfit_engine.drape.metrics import surface_penetration
    from vfit_engine.io.meshdata import MeshData
    from vfit_engine.sim.contact_points import contact_points
    from vfit_engine.sim.model import Model
    from vfit_engine.sim.solver_pd import SolverPD
    from vfit_engine.sim.solver_settings import ContactSettings, PDSettings
    from vfit_engine.sim.springs import grid_polygons

    sphere = trimesh.creation.icosphere(subdivisions=3, radius=0.08)
    v0, tris = np.ascontiguousarray(sphere.vertices, dtype=np.float64), np.ascontiguousarray(sphere.faces)
    rise, frames = np.array([0.0, 0.04, 0.0]), 6
    col = _moving(v0, tris, rise, frames, 0.01)
    pos, fv, fo = grid_polygons(12, 12, 0.24, 0.24)
    start = np.ascontiguousarray(pos + [0.0, 0.0825, 0.0])  # 2.5 mm above the top
    model = Model.from_polygons(fv, fo, pos, "cotton")
    solver = SolverPD(model, PDSettings(band_weight=1.0), ContactSettings(skin=0.002, friction=0.5), body=col,
                      points=contact_points(fv, fo, pos, spacing=0.007))
    state = solver.init_state(1 / 120, pos=start)
    solver.max_push = 0.08
    tri = MeshData(start, fo, fv).triangles()
    top = []

    def check(k):
        s = surface_penetration(col, state.pos, tri)
        assert s["surface_inside_percent"] == 0.0 and s["surface_max_depth_mm"] == 0.0, (k, s)
        top.append(state.pos[:, 1].max() - start[:, 1].max())

    _drive(solver, state, col, v0, rise, frames, 30, 4, np.tile(rise * 30, (len(v0), 1)), each=check)
    d, _, _, _ = col.query(state.pos, max_out=0.05, max_in=np.inf)
    assert np.all(d > 0.0)
    for k, up in enumerate(top, start=1):  # carried up with the sphere's top, never left behind
        assert 0.04 * k - 0.005 < up < 0.04 * k + 0.015, (k, up)
    assert solver.refactors == 0 and model.max_stretch(state.pos) < 0.05


@pytest.fixture(scope="module")
def tube(body_model, tmp_path_factory):
    """A coarse short tube skirt on the default woman (tests/test_animate.py's small run), placed (not draped)."""
    from vfit_engine.body.resolve import default_body
    from vfit_engine.garment.demo_skirt import tube_skirt
    from vfit_engine.garment.garment import load_garment
    from vfit_engine.io.mesh import write_mesh

    body = default_body(body_model, "female")
    path = tmp_path_factory.mktemp("tube") / "tube.obj"
    write_mesh(path, tube_skirt(body.surface, body_model.body_tris, around=24, rows=4, clearance=0.03,
                                below_crotch=-0.03))
    return load_garment(str(path), units="m"), body


def test_the_walk_runs_on_either_solver_with_the_same_figures(tube, body_model, monkeypatch):
    """The animate loop runs on SolverPD when the drape's settings are projective (drape.settings.projective), on
    SolverVerlet otherwise, through the same calls: the same figures of every frame, within the bars on the walk's
    first frame. The moving cloth goes without the still drape's stiffness damping (it would resist the swing of
    a leg as much as a stretch)."""
    import vfit_engine.animate.loop as animate_loop
    from vfit_engine.animate.loop import AnimateSettings, run_animation
    from vfit_engine.animate.motion import load_clip
    from vfit_engine.animate.outputs import FRAME_KEYS, quality
    from vfit_engine.drape import DrapeSettings, prepare_drape
    from vfit_engine.drape.settings import DRAPE_STIFFNESS_DAMPING, projective

    built = []
    build = animate_loop.build_solver
    monkeypatch.setattr(animate_loop, "build_solver", lambda setup, dst: built.append(dst.solver) or build(setup, dst))
    garment, body = tube
    clip = load_clip(body_model, "walk")
    verlet_settings = DrapeSettings(ground=False)
    pd_settings = projective(verlet_settings, history=5)  # quasi-Newton iterations, in motion too (qn_move_limit)
    setup = prepare_drape(garment, body, body_model, settings=pd_settings)  # (the solver plays no part in it)
    st = AnimateSettings(frames=1, blend_s=0.2)
    pd, verlet = (run_animation(setup, setup.start, clip, body_model, st, dst) for dst in (pd_settings, verlet_settings))
    assert pd.info["solver"] == "SolverPD" and verlet.info["solver"] == "SolverVerlet"
    assert pd.info["substeps"] == 4 and verlet.info["substeps"] == 16  # 1/120 s and 1/480 s steps a 1/30 s frame
    assert set(pd.figures[1]) == set(verlet.figures[1]) >= set(FRAME_KEYS)
    assert quality(pd.figures)["passed"], quality(pd.figures)
    assert pd.info["matrix_refactors"] > 0  # the bands re-weighed as the cloth moves (PDSettings.band_weight)
    assert pd_settings.solver.stiffness_damping == DRAPE_STIFFNESS_DAMPING > 0
    assert built[0].stiffness_damping == 0.0 and built[0].iterations == st.pd_iterations and built[0].history == 5


@pytest.mark.parametrize("args, words", [
    (["--pin", "none"], "--pin is for a garment mesh"),
    (["--collider", "bone-spheres"], "--collider is for a garment mesh"),
])
@needs_shared
def test_animate_refuses_mesh_options_on_a_pattern(tmp_path, args, words):
    r = CliRunner().invoke(cli, ["animate", str(SKIRT), "-o", str(tmp_path / "o"), *args])
    assert r.exit_code == 2 and words in r.output and len(r.output.strip().splitlines()) == 1, r.output
    assert not (tmp_path / "o").exists()


def test_animate_refuses_a_broken_pattern_in_one_line(tmp_path):
    bad = tmp_path / "broken.json"
    bad.write_text(json.dumps({"pattern": {"panels": {"front": {"vertices": [[0, 0], [1, 0]], "edges": []}}}}))
    out = tmp_path / "o"
    out.mkdir()
    (out / "report.json").write_text("{}")  # an earlier run's: kept when this one fails before it starts
    r = CliRunner().invoke(cli, ["animate", str(bad), "-o", str(out), "-q"])
    assert r.exit_code == 2 and str(bad) in r.output and len(r.output.strip().splitlines()) == 1, r.output
    assert "Traceback" not in r.output and (out / "report.json").read_text() == "{}"


def test_animate_refuses_pattern_options_on_a_mesh(tmp_path):
    skirt = Path(__file__).resolve().parents[1] / "data" / "garments" / "skirt.obj"
    for opt, value in (("--spacing", "15"), ("--arrange", "wrap")):
        r = CliRunner().invoke(cli, ["animate", str(skirt), "-o", str(tmp_path / "o"), opt, value])
        assert r.exit_code == 2 and opt in r.output and len(r.output.strip().splitlines()) == 1, r.output
        assert not (tmp_path / "o").exists()


@needs_shared
def test_animate_sews_a_pattern_and_walks_it_on_the_projective_solver(tmp_path, monkeypatch):
    """``vfit animate PATTERN``: the shared skirt meshed coarsely (50 mm), sewn round the still body (its rest
    drape cut to 45 frames here: sewn by frame 30), then 2 frames of the walk on SolverPD; the frames keep the
    panels (groups) and their seams shut."""
    import functools

    import vfit_engine.drape
    from vfit_engine.io.mesh import read_mesh
    from vfit_engine.pattern.load import load
    from vfit_engine.pattern.mesh import mesh_pattern

    monkeypatch.setattr(vfit_engine.drape, "DrapeSettings",
                        functools.partial(vfit_engine.drape.DrapeSettings, max_frames=45))
    out = tmp_path / "walk"
    r = CliRunner().invoke(cli, ["animate", str(SKIRT), "--spacing", "50", "--frames", "2", "--every", "2",
                                 "--blend", "0.2", "-o", str(out), "-q"])
    assert r.exit_code == 0, r.output
    report = json.loads((out / "report.json").read_text())
    assert report["solver"] == "SolverPD" and report["substeps_per_frame"] == 4
    assert report["pattern"]["panel_count"] == 4 and len(report["frame_figures"]) == 3
    assert report["quality"]["passed"] and report["rest_drape"]["frames"] == 45
    frame = read_mesh(out / "frame_0002.obj")
    assert [name for name, _ in frame.groups] == ["front", "right", "back", "left"]
    pairs = mesh_pattern(load(SKIRT)[0], 0.05).seam_pairs
    gap = np.linalg.norm(frame.verts[pairs[:, 0]] - frame.verts[pairs[:, 1]], axis=1)
    assert gap.max() < 0.002  # the seams stay shut as the body walks
    body0, body2 = read_mesh(out / "body_0000.obj").verts, read_mesh(out / "body_0002.obj").verts
    assert np.linalg.norm(body2 - body0, axis=1).max() > 0.005  # the body moved

