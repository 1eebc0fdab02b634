"""The drape pipeline: pins that follow the body, the frame loop, convergence, divergence, quality."""
from pathlib import Path

import numpy as np
import pytest

from vfit_engine.errors import InputError

GARMENTS = Path(__file__).resolve().parents[2] / "shared" / "assets" / "garments"
needs_shared = pytest.mark.skipif(not GARMENTS.is_dir(), reason="../shared not present")


def skirt_mesh(body_verts, body_tris, around=40, rows=8):
    """An open cylinder (quads, with UVs) from the body's waist to below its crotch, clear of the hips."""
    from vfit_engine.garment.demo_skirt import tube_skirt

    return tube_skirt(body_verts, body_tris, around=around, rows=rows, clearance=0.015, below_crotch=0.08)


@pytest.fixture(scope="module")
def female(body_model):
    from vfit_engine.body.model import N_BODY
    from vfit_engine.collide.body_mesh import MeshCollider

    verts = body_model.default_verts("female")
    body = np.ascontiguousarray(verts[:N_BODY])
    return dict(full=verts, body=body, tris=body_model.body_tris, collider=MeshCollider(body, body_model.body_tris))


@pytest.fixture(scope="module")
def skirt_run(female):
    from vfit_engine.sim.drape import drape_garment

    mesh = skirt_mesh(female["body"], female["tris"])
    res = drape_garment(mesh, None, female["body"], female["body"], female["tris"], body_collider=female["collider"])
    return mesh, res


def test_skirt_drape_invariants(female, skirt_run):
    from vfit_engine.sim.drape import DrapeSettings

    mesh, res = skirt_run
    st = DrapeSettings()
    assert res.converged and res.frames < st.max_frames
    assert res.pos.shape == mesh.verts.shape and np.all(np.isfinite(res.pos))
    # pins: the waist loop, fixed to their attachment on the body
    assert res.pin_indices.size == 40 and np.all(res.pos[res.pin_indices] == res.pin_targets)
    pen = female["collider"].penetration(res.pos)
    assert pen["max_depth_m"] <= 0.002 and pen["inside_count"] <= 0.005 * len(res.pos)
    assert res.metrics["max_strain"] <= 0.10 and res.metrics["p99_strain"] <= 0.05
    # the skirt hung down under gravity (it did not stay put or fly away)
    assert 0.0 < np.mean(res.pos[:, 1] - mesh.verts[:, 1]) * -1 < 0.05
    assert res.steps == res.frames * st.substeps
    # settled: the fastest particle's mean speed over the last window is below the bar
    assert res.settings["window_speed"] < st.settle_max_speed
    from dataclasses import replace

    from vfit_engine.sim.report import meets_bars

    assert meets_bars(res)
    for key, bad in (("max_strain", 0.11), ("p99_strain", 0.051), ("deep_count", 1), ("inside_fraction", 0.006)):
        assert not meets_bars(replace(res, metrics={**res.metrics, key: bad}))
    assert not meets_bars(replace(res, converged=False))


def test_limiter_sweeps_from_the_pins():
    """The strain-limit sweep visits springs by their graph distance from the pins, so corrections
    travel down a cloth hanging from them in few sweeps (Gauss-Seidel along the load path)."""
    from vfit_engine.garment.springs import grid_polygons
    from vfit_engine.kernels.strain_limit import limit_strain
    from vfit_engine.sim.limiter import order_from_pins
    from vfit_engine.sim.materials import resolve_material
    from vfit_engine.sim.model import Model
    from vfit_engine.sim.solver_verlet import SolverVerlet, VerletSettings

    pos, fv, fo = grid_polygons(4, 13, 0.15, 0.6)  # rows 5 cm apart along z
    top = np.flatnonzero(pos[:, 2] == pos[:, 2].max())
    model = Model.from_polygons(fv, fo, pos, resolve_material("cotton"), pin_indices=top)
    solver = SolverVerlet(model, VerletSettings(strain_limit=0.01))
    order_from_pins(solver, top, model.particle_count)
    li, lj = solver._lim_i, solver._lim_j
    row = np.round((pos[:, 2].max() - pos[:, 2]) / 0.05).astype(int)
    key = np.minimum(row[li], row[lj])
    assert key[0] == 0 and np.all(np.diff(key) >= 0)
    # the pins pulled 1 cm away from the cloth: three sweeps from the pins leave less stretch than
    # three in the reverse order (the pinned springs last)
    pulled = pos.copy()
    pulled[top, 2] += 0.01
    w = np.where(np.isin(np.arange(len(pos)), top), 0.0, 1.0)
    worst = []
    for order in (slice(None), slice(None, None, -1)):
        x = pulled.copy()
        limit_strain(x, w, np.stack([li[order], lj[order]], axis=1), solver._lim_len[order], iterations=3)
        worst.append(model.spring_strain(x)[model.spring_type == 0].max())
    print("max strain after 3 sweeps: pin order %.4f, reverse %.4f" % tuple(worst))
    assert worst[0] < 0.9 * worst[1]


def test_stretch_zone_raises_the_limit_near_the_opening_only():
    """A too-small opening may stretch by its required strain, and so may the cloth within the zone
    width of it (along the cloth); the rest keeps its limit."""
    from vfit_engine.garment.springs import grid_polygons
    from vfit_engine.sim.limiter import relax_zone
    from vfit_engine.sim.materials import resolve_material
    from vfit_engine.sim.model import Model
    from vfit_engine.sim.solver_verlet import SolverVerlet, VerletSettings

    pos, fv, fo = grid_polygons(5, 21, 0.2, 0.2)  # rows 1 cm apart along z
    model = Model.from_polygons(fv, fo, pos, resolve_material("cotton"))
    solver = SolverVerlet(model, VerletSettings(strain_limit=0.015))
    before = solver._lim_len.copy()
    edge = np.flatnonzero(pos[:, 2] == pos[:, 2].min())  # the 'opening': one boundary row
    relax_zone(solver, model, edge, 0.12, 0.015, 0.03)
    far = np.maximum(pos[solver._lim_i, 2], pos[solver._lim_j, 2]) - pos[:, 2].min()
    ratio = solver._lim_len / before
    assert np.allclose(ratio[far <= 0.03 + 1e-9], 1.12 / 1.015)  # rows 0-3: within 3 cm
    assert np.all(ratio[far > 0.03 + 1e-9] == 1.0)


def test_drape_is_deterministic(female, skirt_run):
    from vfit_engine.sim.drape import DrapeSettings, drape_garment

    mesh, first = skirt_run
    st = DrapeSettings(max_frames=30)
    a = drape_garment(mesh, None, female["body"], female["body"], female["tris"], settings=st,
                      body_collider=female["collider"])
    b = drape_garment(mesh, None, female["body"], female["body"], female["tris"], settings=st,
                      body_collider=female["collider"])
    assert a.pos.tobytes() == b.pos.tobytes()
    assert not a.converged and a.frames == 30


def test_divergence_is_detected_at_once(female):
    from vfit_engine.sim.drape import DrapeDiverged, DrapeSettings, drape_garment

    mesh = skirt_mesh(female["body"], female["tris"], around=16, rows=4)

    def poison(frame, pos, state):
        if frame == 3:
            state.pos[5, 1] = np.nan

    with pytest.raises(DrapeDiverged) as info:
        drape_garment(mesh, None, female["body"], female["body"], female["tris"], body_collider=female["collider"],
                      settings=DrapeSettings(max_frames=20), on_frame=poison)
    exc = info.value
    assert exc.exit_code == 4 and exc.frame == 4 and exc.last_good_frame == 3
    assert "diverged at frame 4" in str(exc) and "\n" not in str(exc)
    assert np.all(np.isfinite(exc.last_good))

    # a runaway speed (not NaN) is divergence too
    def kick(frame, pos, state):
        if frame == 2:
            state.pos_prev[:] = state.pos - [0.0, 0.0, 0.2]  # the whole cloth at ~100 m/s

    with pytest.raises(DrapeDiverged, match="m/s"):
        drape_garment(mesh, None, female["body"], female["body"], female["tris"], body_collider=female["collider"],
                      settings=DrapeSettings(max_frames=20), on_frame=kick)


def test_pins_follow_the_body(female):
    from vfit_engine.sim.drape import PinAttachment

    rng = np.random.default_rng(3)
    body, tris = female["body"], female["tris"]
    idx = rng.choice(body.shape[0], 20, replace=False)
    normals = np.cross(body[tris[:, 1]] - body[tris[:, 0]], body[tris[:, 2]] - body[tris[:, 0]])
    # points 1 cm out along a face normal
    t = rng.choice(tris.shape[0], 20, replace=False)
    centre = body[tris[t]].mean(axis=1)
    pts = centre + 0.01 * normals[t] / np.linalg.norm(normals[t], axis=1, keepdims=True)
    garment = np.concatenate([pts, np.zeros((5, 3))])
    att = PinAttachment.attach(garment, np.arange(20), body, tris)
    # the closest triangle is the one the point stands on, or a nearer one in a concave spot
    assert np.all(att.offset <= 0.01 + 1e-12) and np.median(att.offset) > 0.0099
    same = att.positions(body, tris, min_offset=-np.inf)
    assert np.allclose(same, pts, atol=1e-12)  # on the same body the pins stay exactly where they are
    moved = att.positions(body + [0.1, -0.2, 0.05], tris, min_offset=-np.inf)
    assert np.allclose(moved - same, [0.1, -0.2, 0.05], atol=1e-12)
    # a rotated body carries its pins round with it
    c, s_ = np.cos(0.3), np.sin(0.3)
    rot = np.array([[c, 0, s_], [0, 1, 0], [-s_, 0, c]])
    assert np.allclose(att.positions(body @ rot.T, tris, min_offset=-np.inf), same @ rot.T, atol=1e-12)
    # heights are clamped to the minimum (a pin never sits inside the body)
    lifted = att.positions(body, tris, min_offset=0.02)
    assert np.allclose(np.linalg.norm(lifted - same, axis=1), 0.02 - att.offset, atol=1e-12)
    assert np.allclose(att.positions(body, tris)[att.offset >= 0], same[att.offset >= 0], atol=1e-12)


def _cylinder(radius, n=24, y=0.0):
    import trimesh

    body = trimesh.creation.cylinder(radius=radius, height=0.4, sections=n)
    # trimesh's cylinder runs along Z: stand it up (Y up)
    v = body.vertices[:, [0, 2, 1]] * [1.0, 1.0, -1.0]
    return np.ascontiguousarray(v + [0.0, y, 0.0]), np.ascontiguousarray(body.faces, dtype=np.int64)


def test_waistband_pins_are_spread_evenly_on_a_wider_body():
    """A band pinned round a cylinder, refitted on a wider cylinder that bulges on one side only."""
    from vfit_engine.io.mesh import MeshData
    from vfit_engine.sim.drape import PinAttachment
    from vfit_engine.sim.pin_fit import fit_pins, pinned_loops

    ref, tris = _cylinder(0.15, n=48)
    big = ref.copy()
    # +6 % girth, all of it on the +x side: following the triangles would stretch the band there only
    big[:, 0] = np.where(big[:, 0] > 0, big[:, 0] * 1.19, big[:, 0])
    k = 32
    ang = np.linspace(0, 2 * np.pi, k, endpoint=False)
    ring = np.stack([0.16 * np.cos(ang), np.zeros(k), 0.16 * np.sin(ang)], axis=1)  # 1 cm ease
    verts = np.concatenate([ring, ring - [0.0, 0.05, 0.0]])
    quads = np.array([[i, (i + 1) % k, k + (i + 1) % k, k + i] for i in range(k)], dtype=np.int64)
    mesh = MeshData(verts=verts, face_verts=quads.ravel(), face_offsets=np.arange(0, 4 * k + 1, 4))
    idx = np.arange(k, dtype=np.int64)
    loops = pinned_loops(mesh, idx)
    assert len(loops) == 1 and sorted(loops[0][0].tolist()) == idx.tolist()
    att = PinAttachment.attach(verts, idx, ref, tris)
    follow = att.positions(big, tris, min_offset=0.002)
    gaps = np.linalg.norm(np.roll(ring, -1, 0) - ring, axis=1)
    assert np.max(np.linalg.norm(np.roll(follow, -1, 0) - follow, axis=1) / gaps - 1) > 0.08
    kept, _, target, info = fit_pins(mesh, idx, att, big, tris, 0.002, 0.03, 0.015)
    assert info["refitted_groups"] == 1 and info["released_stretched"] == 0 and kept.tolist() == idx.tolist()
    strain = np.linalg.norm(np.roll(target, -1, 0) - target, axis=1) / gaps - 1
    # the ease is used first, then the remaining stretch is shared: the band is as long as it can be
    # made on this body, and every edge stretches about the same
    assert strain.max() - strain.min() < 0.01 and strain.max() < 0.03
    r = np.hypot(target[:, 0] / np.where(target[:, 0] > 0, 1.19, 1.0), target[:, 2])
    assert np.all(r >= 0.15 + 0.002 - 1e-3)  # nothing within the skin of the body
    # on the body it was modelled on the band keeps its attachment
    _, _, same, info = fit_pins(mesh, idx, att, ref, tris, 0.002, 0.03, 0.015)
    assert info["refitted_groups"] == 0 and np.allclose(same, ring, atol=1e-12)


def test_pin_patch_is_moved_rigidly():
    from vfit_engine.sim.pin_fit import fit_patch

    ref, tris = _cylinder(0.15, n=48)
    rng = np.random.default_rng(5)
    ang = rng.uniform(-0.5, 0.5, 12)
    rest = np.stack([0.155 * np.cos(ang), rng.uniform(-0.05, 0.05, 12), 0.155 * np.sin(ang)], axis=1)
    rot = np.array([[np.cos(0.2), 0, np.sin(0.2)], [0, 1, 0], [-np.sin(0.2), 0, np.cos(0.2)]])
    # triangle-following targets: the patch turned and shifted, plus a non-rigid wobble
    follow = rest @ rot.T + [0.0, 0.01, 0.0] + rng.normal(0, 0.002, rest.shape)
    out = fit_patch(rest, follow, ref, tris, 0.002)
    dist = lambda p: np.linalg.norm(p[:, None] - p[None], axis=2)  # noqa: E731
    assert np.allclose(dist(out), dist(rest), atol=1e-9)  # rigid: no spring between pins stretched
    assert np.allclose(out, rest @ rot.T + [0.0, 0.01, 0.0], atol=0.003)
    assert np.all(np.hypot(out[:, 0], out[:, 2]) >= 0.15 + 0.002 - 1e-3)


def test_read_pin_file(tmp_path):
    from vfit_engine.sim.drape import read_pin_file

    p = tmp_path / "pins.txt"
    p.write_text("# waist\n3\n1\n\n3  # again\n")
    assert read_pin_file(p, 5).tolist() == [1, 3]
    for text, match in (("1\nx\n", "line 2"), ("7\n", "does not exist"), ("-1\n", "does not exist")):
        p.write_text(text)
        with pytest.raises(InputError, match=match):
            read_pin_file(p, 5)
    with pytest.raises(InputError, match="cannot read"):
        read_pin_file(tmp_path / "missing.txt", 5)


def test_auto_spheres_lie_inside_and_cover(body_model, female):
    from vfit_engine.collide.auto_spheres import bone_points, fit_spheres

    centres, radii = fit_spheres(female["body"], female["tris"], female["collider"],
                                 extra_points=bone_points(body_model, female["full"]))
    assert 20 < len(radii) <= 400 and np.all(radii >= 0.008)
    d, _, _, _ = female["collider"].query(centres, max_out=0.0, max_in=1.0)
    assert np.allclose(-d, radii)  # inscribed: each sphere touches the body from inside
    # the torso is covered: waist-to-chest surface vertices lie within 1 cm of a sphere
    b = female["body"]
    torso = b[(b[:, 1] > 0.0) & (b[:, 1] < 0.3) & (np.abs(b[:, 0]) < 0.12)]
    gap = np.min(np.linalg.norm(torso[:, None] - centres[None], axis=2) - radii[None], axis=1)
    assert np.percentile(gap, 95) < 0.01


# The female suits' short-sleeve hems are smaller than the arm they sit on: female_sportsuit01's are
# 218 and 225 mm round against at least 238 and 239 mm of arm within 3 cm either side of them on the
# default female body (test_openings.py); going round the arm 2 mm clear needs >= 11.7 % and 15.1 %
# strain there, beyond the 10 % bar: the asset cannot meet it with its own rest lengths.
_SLEEVE_HEM = pytest.mark.xfail(reason="female suit sleeve hems are smaller than the arm: >= 11.7 % strain needed "
                                       "(vfit_engine.garment.openings), bar 10 %", strict=True)


@needs_shared
@pytest.mark.parametrize("name, delta_cm", [
    ("male_casualsuit02", -5.0),
    ("male_casualsuit06", 0.0),
    pytest.param("female_sportsuit01", 0.0, marks=_SLEEVE_HEM),
    ("male_casualsuit02", 5.0),
    ("male_casualsuit06", 5.0),
])
def test_shared_garment_quality(morpher, name, delta_cm):
    """Acceptance: converged, finite, nothing deeper than 2 mm, <= 0.5 % inside, strain p99 <= 5 %, max <= 10 %.

    As ``vfit drape`` does by default: the garment is transferred to the body (mhclo-delta) and
    graded there (rest lengths of the transferred garment).
    """
    from vfit_engine.garment.garment import load_garment
    from vfit_engine.garment.mhclo import parse_mhclo
    from vfit_engine.sim.drape import drape_garment

    g = load_garment(GARMENTS / name / f"{name}.obj")
    binding = parse_mhclo(g.mhclo_path)
    ref = morpher.model.default_verts(binding.gender)
    body = ref
    if delta_cm:
        start = morpher.measurer.measure(ref, "iso").cm()
        body = morpher.solve({"waist": (start["waist"] + delta_cm) / 100, "hips": (start["hips"] + delta_cm) / 100},
                             gender=binding.gender).verts
    res = drape_garment(g.mesh, g.pieces, body, ref, morpher.model.body_tris, transfer="auto", mhclo=binding,
                        rest="transferred")
    m = res.metrics
    assert res.converged and m["finite"]
    assert m["deep_count"] == 0 and m["inside_fraction"] <= 0.005
    assert m["p99_strain"] <= 0.05 and m["max_strain"] <= 0.10
    if delta_cm > 0:
        # graded to a wider body: the garment as given would be stretched
        assert m["garment_strain"]["p99"] > m["p99_strain"]


def test_rest_transferred_grades_the_garment(female):
    """rest="transferred": the cloth starts unstretched on a bigger body; against the garment it is stretched."""
    from vfit_engine.sim.drape import DrapeSettings, drape_garment

    tris = female["tris"]
    mesh = skirt_mesh(female["body"], tris, around=16, rows=3)
    centre = female["body"].mean(axis=0)
    big = centre + 1.08 * (female["body"] - centre)
    st = DrapeSettings(max_frames=1)
    graded = drape_garment(mesh, None, big, female["body"], tris, settings=st, transfer="dqs", rest="transferred")
    fixed = drape_garment(mesh, None, big, female["body"], tris, settings=st, transfer="none", rest="transferred")
    assert graded.settings["transfer"]["rest"] == "transferred" and graded.settings["transfer"]["pin_gap_mm"]["max"] < 1e-6
    # one frame after a start at rest: within the strain limit; the same positions against the garment: stretched
    assert graded.metrics["max_strain"] < 0.03 and graded.metrics["garment_strain"]["p99"] > 0.04
    # nothing transferred: the rest lengths are the garment's, and so is the strain metric
    assert fixed.metrics["p99_strain"] == pytest.approx(fixed.metrics["garment_strain"]["p99"], rel=1e-9)
    with pytest.raises(InputError, match="rest"):
        drape_garment(mesh, None, big, female["body"], tris, settings=st, transfer="dqs", rest="pattern")


def test_transfer_is_the_identity_on_the_same_body(female):
    from vfit_engine.garment.transfer import BodyFrames
    from vfit_engine.garment.transfer import transfer_garment

    mesh = skirt_mesh(female["body"], female["tris"], around=16, rows=3)
    for method in ("auto", "dqs", "lbs", "none"):
        out, info = transfer_garment(mesh.verts, female["full"], female["body"], female["tris"], method)
        assert np.array_equal(out, mesh.verts) and info["identity"] and info["max_move_mm"] == 0.0
    assert info["method"] == "none"
    # auto without a .mhclo binding is dqs; evaluated in full, dqs on the same body moves nothing either
    assert transfer_garment(mesh.verts, female["body"], female["body"], female["tris"])[1]["method"] == "dqs"
    frames = BodyFrames(female["body"], female["tris"])
    assert np.allclose(frames.transfer(mesh.verts, female["body"], "dqs"), mesh.verts, atol=1e-9)


def test_transfer_rejects_bad_methods(female):
    from vfit_engine.garment.transfer import transfer_garment
    from vfit_engine.sim.drape import drape_garment

    mesh = skirt_mesh(female["body"], female["tris"], around=16, rows=3)
    with pytest.raises(InputError, match="unknown transfer method"):
        transfer_garment(mesh.verts, female["body"], female["body"] + 0.01, female["tris"], "warp")
    with pytest.raises(InputError, match="mhclo"):
        transfer_garment(mesh.verts, female["body"], female["body"] + 0.01, female["tris"], "mhclo-delta")
    with pytest.raises(InputError, match="unknown transfer method"):
        drape_garment(mesh, None, female["body"] + 0.01, female["body"], female["tris"], transfer="warp")


def test_transferred_start_agrees_with_the_pins(female):
    """On a translated body dqs moves the garment by the translation, exactly where its pins go."""
    from vfit_engine.garment.transfer import transfer_garment
    from vfit_engine.sim.drape import DrapeSettings, drape_garment

    shift = np.array([0.03, 0.05, -0.02])
    body, tris = female["body"] + shift, female["tris"]
    mesh = skirt_mesh(female["body"], tris, around=16, rows=3)
    out, info = transfer_garment(mesh.verts, female["full"], body, tris, "dqs")
    assert info["method"] == "dqs" and not info["identity"]
    assert np.allclose(out, mesh.verts + shift, atol=1e-9)
    assert abs(info["max_move_mm"] - 1000 * np.linalg.norm(shift)) < 1e-6
    res = drape_garment(mesh, None, body, female["body"], tris, settings=DrapeSettings(max_frames=3), transfer="dqs")
    tinfo = res.settings["transfer"]
    assert tinfo["method"] == "dqs" and tinfo["pin_gap_mm"]["max"] < 1e-6
    assert np.allclose(res.pin_targets, mesh.verts[res.pin_indices] + shift, atol=1e-9)
    # without the transfer the same pins start a translation away from their targets
    none = drape_garment(mesh, None, body, female["body"], tris, settings=DrapeSettings(max_frames=3))
    assert abs(none.settings["transfer"]["pin_gap_mm"]["max"] - 1000 * np.linalg.norm(shift)) < 1e-6
