"""Garment transfer: ARAP frames, LBS/DQS blending, mhclo re-fitting, the ``transfer`` CLI command."""
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from vfit_engine.body.model import N_BODY
from vfit_engine.errors import InputError
from vfit_engine.garment.arap import MIN_COT_WEIGHT, arap_rotations, cotangent_weights
from vfit_engine.rotations import dual_quat_to_rigid, quat_to_rotation, rigid_to_dual_quat, rotation_to_quat
from vfit_engine.garment.transfer import BodyFrames, blend_dqs, blend_lbs, transfer

GARMENTS = Path(__file__).resolve().parents[1] / ".." / "shared" / "assets" / "garments"
SUIT = GARMENTS / "female_casualsuit01" / "female_casualsuit01.obj"
needs_shared = pytest.mark.skipif(not SUIT.is_file(), reason="../shared not present")


def random_rotations(rng, n):
    """(n, 3, 3) rotations from normalised random quaternions."""
    q = rng.normal(size=(n, 4))
    return quat_to_rotation(q / np.linalg.norm(q, axis=1, keepdims=True))


def rigid(rng):
    return random_rotations(rng, 1)[0], rng.normal(0.0, 0.5, 3)


@pytest.fixture(scope="module")
def female(body_model):
    return body_model.default_verts("female")


@pytest.fixture(scope="module")
def frames(female, body_model):
    return BodyFrames(female, body_model.body_tris)


@pytest.fixture(scope="module")
def cloud(female):
    """2,000 seeded points within ~2 cm of the body surface: a stand-in garment."""
    rng = np.random.default_rng(7)
    return female[rng.integers(0, N_BODY, 2000)] + rng.normal(0.0, 0.01, (2000, 3))


@pytest.fixture(scope="module")
def suit():
    from vfit_engine.garment.garment import load_garment
    from vfit_engine.garment.mhclo import parse_mhclo

    if not SUIT.is_file():
        pytest.skip("../shared not present")
    g = load_garment(SUIT)
    return g, parse_mhclo(g.mhclo_path)


# ---------------------------------------------------------------------- ARAP
def test_cotangent_weights_of_a_square():
    """Unit square split on its diagonal: boundary edges face 45 deg (w = cot/2 = 1/2), the diagonal 90 deg (0)."""
    verts = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    edges, w = cotangent_weights(verts, np.array([[0, 1, 2], [0, 2, 3]]))
    got = {tuple(e): x for e, x in zip(edges.tolist(), w)}
    assert got[(0, 2)] == pytest.approx(MIN_COT_WEIGHT)
    for e in ((0, 1), (1, 2), (2, 3), (0, 3)):
        assert got[e] == pytest.approx(0.5, abs=1e-12)


def test_arap_returns_the_rigid_rotation_everywhere(female, frames):
    rng = np.random.default_rng(1)
    for _ in range(3):
        rot, t = rigid(rng)
        got = frames.rotations(female @ rot.T + t)
        assert got.shape == (N_BODY, 3, 3)
        assert np.abs(got - rot).max() < 1e-9


def test_arap_matches_per_vertex_reference():
    """Batched rotations against a slow per-vertex loop on a seeded, non-rigidly deformed sphere."""
    import trimesh

    sphere = trimesh.creation.icosphere(subdivisions=2)
    src, tris = np.asarray(sphere.vertices), np.asarray(sphere.faces, dtype=np.int64)
    rng = np.random.default_rng(3)
    dst = src * np.array([1.3, 0.8, 1.1]) + rng.normal(0.0, 0.02, src.shape)
    edges, w = cotangent_weights(src, tris)
    got = arap_rotations(src, dst, edges, w)
    for i in range(0, len(src), 7):
        s = np.zeros((3, 3))
        for (a, b), wij in zip(edges, w):
            if i in (a, b):
                j = b if a == i else a
                s += wij * np.outer(src[j] - src[i], dst[j] - dst[i])
        u, _, vt = np.linalg.svd(s)
        r = vt.T @ u.T
        if np.linalg.det(r) < 0:
            r = vt.T @ np.diag([1.0, 1.0, -1.0]) @ u.T
        assert np.abs(got[i] - r).max() < 1e-10
        assert np.linalg.det(got[i]) == pytest.approx(1.0)


# ---------------------------------------------------------------------- quaternions and blending
def test_quaternion_round_trip_all_branches():
    rng = np.random.default_rng(5)
    half_turns = np.array([np.diag(d) for d in ([1.0, -1, -1], [-1.0, 1, -1], [-1.0, -1, 1])])
    rots = np.concatenate([random_rotations(rng, 500), half_turns, np.eye(3)[None]])
    assert np.abs(quat_to_rotation(rotation_to_quat(rots)) - rots).max() < 1e-12


def test_dual_quaternion_round_trip():
    rng = np.random.default_rng(6)
    rot, t = random_rotations(rng, 100), rng.normal(0.0, 2.0, (100, 3))
    r2, t2 = dual_quat_to_rigid(*rigid_to_dual_quat(rot, t))
    assert np.abs(r2 - rot).max() < 1e-12 and np.abs(t2 - t).max() < 1e-12


def _one_transform_everywhere(rng, n_body):
    """Source/target bodies and per-vertex rotations that all encode one rigid transform."""
    rot, t = rigid(rng)
    src = rng.normal(0.0, 0.3, (n_body, 3))
    return rot, t, src, src @ rot.T + t, np.repeat(rot[None], n_body, axis=0)


@pytest.mark.parametrize("blend", [blend_dqs, blend_lbs])
def test_blending_identical_transforms_gives_that_transform(blend):
    rng = np.random.default_rng(11)
    rot, t, src, dst, rots = _one_transform_everywhere(rng, 50)
    pts = rng.normal(0.0, 0.5, (300, 3))
    idx = rng.integers(0, 50, (300, 6))
    w = rng.random((300, 6))
    w /= w.sum(axis=1, keepdims=True)
    assert np.abs(blend(pts, idx, w, rots, src, dst) - (pts @ rot.T + t)).max() < 1e-12


def test_dqs_sign_alignment():
    """Negating some quaternions (the same rotations) must not change the DQS result."""
    rng = np.random.default_rng(12)
    rot, t, src, dst, rots = _one_transform_everywhere(rng, 20)
    real, dual = rigid_to_dual_quat(rots, dst - np.einsum("vij,vj->vi", rots, src))
    flip = np.where(rng.random(20) < 0.5, -1.0, 1.0)[:, None]
    pts = rng.normal(size=(40, 3))
    idx, w = rng.integers(0, 20, (40, 4)), np.full((40, 4), 0.25)
    out = blend_dqs(pts, idx, w, rots, src, dst, dq=(real * flip, dual * flip))
    assert np.abs(out - (pts @ rot.T + t)).max() < 1e-12


def test_lbs_matches_reference_loop():
    rng = np.random.default_rng(13)
    src, dst = rng.normal(size=(30, 3)), rng.normal(size=(30, 3))
    rots = random_rotations(rng, 30)
    pts, idx = rng.normal(size=(25, 3)), rng.integers(0, 30, (25, 3))
    w = rng.random((25, 3))
    w /= w.sum(axis=1, keepdims=True)
    want = np.array([sum(w[n, j] * (rots[i] @ (pts[n] - src[i]) + dst[i]) for j, i in enumerate(idx[n]))
                     for n in range(25)])
    assert np.abs(blend_lbs(pts, idx, w, rots, src, dst) - want).max() < 1e-12


def test_binding_weights(frames, cloud):
    idx, w = frames.bind(cloud, k=6)
    assert idx.shape == w.shape == (len(cloud), 6)
    assert np.allclose(w.sum(axis=1), 1.0) and (w >= 0).all()
    # nearest first, and the nearest never weighs less than a farther one
    assert (np.diff(w, axis=1) <= 1e-15).all()


# ---------------------------------------------------------------------- transfer
@pytest.mark.parametrize("method", ["lbs", "dqs"])
def test_same_body_is_identity(female, body_model, cloud, method):
    out = transfer(cloud, female, female, method=method, model=body_model)
    assert np.abs(out - cloud).max() < 1e-9


@pytest.mark.parametrize("method", ["lbs", "dqs"])
def test_rigid_motion_of_the_body_moves_the_garment_rigidly(female, body_model, cloud, method):
    """All ARAP frames are the body's rotation, so both blends reduce to it (DQS by construction)."""
    rot, t = rigid(np.random.default_rng(21))
    out = transfer(cloud, female, female @ rot.T + t, method=method, model=body_model)
    assert np.abs(out - (cloud @ rot.T + t)).max() < 1e-9


def test_mhclo_identity_defined(suit, female, body_model):
    """mhclo re-fits the binding, so source == target returns the binding's fit (not the OBJ, which the fit
    misses by the authoring residual); mhclo-delta returns the garment itself."""
    from vfit_engine.garment.mhclo import evaluate_mhclo

    g, b = suit
    fit = evaluate_mhclo(b, female)
    out = transfer(g.verts, female, female, method="mhclo", mhclo=b)
    assert np.array_equal(out, fit)
    assert np.array_equal(transfer(g.verts, female, female, mhclo=b), fit)  # auto -> mhclo
    residual = np.linalg.norm(fit - g.verts, axis=1)
    print(f"mhclo fit vs authored OBJ on the default female body: mean {residual.mean() * 1e3:.1f} mm, "
          f"max {residual.max() * 1e3:.1f} mm")
    assert residual.max() < 0.05
    assert np.array_equal(transfer(g.verts, female, female, method="mhclo-delta", mhclo=b), g.verts)
    with pytest.raises(InputError, match="helper vertices"):
        transfer(g.verts, female[:N_BODY], female[:N_BODY], method="mhclo", mhclo=b)


def test_transfer_to_bigger_body_reduces_penetration(suit, female, body_model, morpher, measurer):
    """+5 cm waist and hips: the transferred suit has fewer vertices inside the new body than the old one."""
    from vfit_engine.collide.body_mesh import MeshCollider
    from vfit_engine.garment.mhclo import evaluate_mhclo

    g, b = suit
    start = measurer.measure(female, "iso", names=("waist", "hips"), mass=False).values
    target = morpher.solve({"waist": start["waist"] + 0.05, "hips": start["hips"] + 0.05}, gender="female").verts
    coll = MeshCollider(target[:N_BODY], body_model.body_tris)
    counts = {}
    for method in ("none", "mhclo", "mhclo-delta", "lbs", "dqs"):
        out = transfer(g.verts, female, target, method=method, mhclo=b, model=body_model)
        counts[method] = coll.penetration(out)["inside_count"]
    # mhclo ignores the input positions: its untransferred counterpart is the binding's fit on the old body
    counts["mhclo fit on old body"] = coll.penetration(evaluate_mhclo(b, female))["inside_count"]
    print("vertices inside the +5 cm body:", counts, f"of {g.mesh.n_verts}")
    for method in ("mhclo-delta", "lbs", "dqs"):
        assert counts[method] < counts["none"]
    assert counts["mhclo"] < counts["mhclo fit on old body"]


@pytest.mark.parametrize("kwargs, match", [
    (dict(garment_verts=np.zeros((5, 2))), "garment vertices"),
    (dict(garment_verts=np.full((5, 3), np.nan)), "NaN"),
    (dict(garment_verts=np.zeros((0, 3))), "no vertices"),
    (dict(source_body=np.zeros((100, 3))), "source body"),
    (dict(target_body=np.full((N_BODY, 3), np.inf)), "target body"),
    (dict(method="cubic"), "unknown transfer method"),
    (dict(k=0), "k must be"),
    (dict(k=True), "k must be"),
    (dict(k=2.5), "k must be"),
    (dict(method="mhclo"), "needs the garment's .mhclo"),
])
def test_bad_inputs(female, body_model, kwargs, match):
    args = dict(garment_verts=female[:5] + 0.01, source_body=female, target_body=female, model=body_model)
    args.update(kwargs)
    with pytest.raises(InputError, match=match):
        transfer(**args)


def test_mhclo_count_mismatch(suit, female):
    g, b = suit
    with pytest.raises(InputError, match="binds"):
        transfer(g.verts[:10], female, female, method="mhclo", mhclo=b)


# ---------------------------------------------------------------------- CLI
@pytest.fixture(scope="module")
def cli_files(tmp_path_factory, body_model, female):
    """A small skirt (metres, UVs) and two body files, the second 4 % wider."""
    from vfit_engine.body.bodyio import write_body
    from vfit_engine.garment.demo_skirt import tube_skirt
    from vfit_engine.io.mesh import write_mesh

    d = tmp_path_factory.mktemp("transfer")
    skirt = tube_skirt(female[:N_BODY], body_model.body_tris, around=24, rows=4, clearance=0.015, below_crotch=0.08)
    write_mesh(d / "skirt.obj", skirt)
    wide = female.copy()
    wide[:, [0, 2]] *= 1.04
    write_body(d / "a.obj", body_model, female)
    write_body(d / "b.obj", body_model, wide)
    return d, skirt


def invoke(*args):
    from vfit_cli.transfer import transfer as command

    return CliRunner().invoke(command, [str(a) for a in args])


def test_cli_transfer_runs(cli_files, tmp_path):
    from vfit_engine.io.mesh import read_mesh

    d, skirt = cli_files
    out = tmp_path / "moved.obj"
    res = invoke(d / "skirt.obj", "--from", d / "a.obj", "--to", d / "b.obj", "--units", "m", "--method", "dqs",
                 "-o", out)
    assert res.exit_code == 0, res.output
    moved = read_mesh(out)
    assert moved.n_verts == skirt.n_verts and np.array_equal(moved.face_verts, skirt.face_verts)
    assert moved.uvs is not None and np.allclose(moved.uvs, skirt.uvs)
    # the skirt widens with the body (about 4 % of its ~15 cm radius), and does not move along Y
    r0 = np.linalg.norm(skirt.verts[:, [0, 2]], axis=1)
    r1 = np.linalg.norm(moved.verts[:, [0, 2]], axis=1)
    assert 1.02 < np.median(r1 / r0) < 1.06
    assert np.abs(moved.verts[:, 1] - skirt.verts[:, 1]).max() < 5e-3


@pytest.mark.parametrize("extra, match", [
    (("--to", "missing.obj"), "not found"),
    ((), "no target body"),
    (("--to", "b.obj", "--waist", "80"), "either --to"),
    (("--to", "b.obj", "--method", "mhclo"), "mhclo"),
    (("--to", "skirt.obj"), "hm08"),
    (("--to", "b.obj", "-o", "x.txt"), "cannot write"),
])
def test_cli_bad_input(cli_files, tmp_path, extra, match):
    d, _ = cli_files
    args = [d / "skirt.obj", "--units", "m", "-o", tmp_path / "o.obj"]
    args += [d / a if a in ("b.obj", "skirt.obj") else (tmp_path / a if a.endswith(".txt") else a) for a in extra]
    res = invoke(*args)
    assert res.exit_code == 2, res.output
    errors = [ln for ln in res.output.splitlines() if ln.startswith("Error")]
    assert len(errors) == 1 and match in errors[0] and "Traceback" not in res.output


@needs_shared
def test_cli_mhclo_needs_helpers(cli_files, tmp_path):
    d, _ = cli_files
    res = invoke(SUIT, "--to", d / "b.obj", "--method", "mhclo", "-o", tmp_path / "o.obj")
    assert res.exit_code == 2
    assert "helper vertices" in res.output and "as vfit builds it from measurements" in res.output


@needs_shared
def test_cli_auto_is_mhclo_delta_as_in_drape(tmp_path):
    """auto = mhclo-delta on a body built from measurements (helpers present), as vfit drape does, and the
    clearance the garment lost is given back."""
    out = tmp_path / "suit.obj"
    res = invoke(SUIT, "--waist", 90, "--hips", 110, "-o", out)
    assert res.exit_code == 0, res.output
    assert "by mhclo-delta" in res.output and "clearance given back to" in res.output and out.is_file()


def test_cli_help():
    res = invoke("--help")
    assert res.exit_code == 0 and "--method" in res.output and "--waist" in res.output


def test_deterministic(female, body_model, cloud):
    wide = female * np.array([1.05, 1.0, 1.03])
    a = transfer(cloud, female, wide, method="dqs", model=body_model)
    b = transfer(cloud, female, wide, method="dqs", model=body_model)
    assert a.tobytes() == b.tobytes()


def test_restore_clearance_gives_back_lost_clearance(female, body_model):
    """A garment 3 mm off the body, carried unchanged onto a body grown 5 mm outward, is put back
    3 mm off it; onto a body shrunk 5 mm nothing moves (clearance is only ever restored outward)."""
    from vfit_engine.collide.body_mesh import MeshCollider, mesh_normals
    from vfit_engine.garment.transfer import restore_clearance

    body, tris = female[:N_BODY], body_model.body_tris
    normals = mesh_normals(body, tris)[3]
    rng = np.random.default_rng(3)
    # the torso: grown 5 mm outward, fingers and toes would run into each other
    torso = np.flatnonzero((body[:, 1] > -0.1) & (body[:, 1] < 0.4) & (np.abs(body[:, 0]) < 0.14))
    k = rng.choice(torso, 800, replace=False)
    garment = body[k] + 0.003 * normals[k]
    for grow, moved in ((0.005, True), (-0.005, False)):
        target = body + grow * normals
        out, restored = restore_clearance(garment, garment, body, target, tris)
        if moved:
            # exact on smooth skin; creases (where the grown body's normals turn or a point's nearest
            # vertex changes) get part of it
            assert abs(np.median(restored) - 0.005) < 1e-5 and np.mean(np.abs(restored - 0.005) < 5e-4) > 0.95
            assert restored.max() < 0.0055
            col = MeshCollider(target, tris)
            d = col.query(out, max_out=0.05, max_in=0.05)[0]
            before = col.query(garment, max_out=0.05, max_in=0.05)[0]
            # 3 mm off the grown body again (bar a few points in creases: under the bust, armpits)
            assert np.median(np.abs(d - 0.003)) < 5e-4 and np.mean(d > 0) > 0.98 and np.mean(before > 0) < 0.1
        else:
            assert np.all(restored == 0) and np.array_equal(out, garment)
