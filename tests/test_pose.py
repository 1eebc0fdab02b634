"""Posing a body: the rig's joints on the body, BVH rotations, skinning; `vfit pose` through CliRunner."""
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from vfit_cli.main import cli
from vfit_engine.body.pose import Z_UP, bone_rotations, file_axes, pose_body, pose_matrices, rig_motion
from vfit_engine.io.bvh import read_bvh

POSES = Path(__file__).resolve().parents[2] / "shared" / "assets" / "poses"
needs_poses = pytest.mark.skipif(not POSES.is_dir(), reason="../shared/assets/poses (MakeHuman poses) absent")
#: Joints well inside the body in any pose (not the fingers, eyes or toes, whose joints lie near the skin).
CORE_JOINTS = ("spine05", "spine03", "spine01", "neck01", "head", "upperarm01.L", "upperarm01.R", "lowerarm01.L",
               "lowerarm01.R", "upperleg01.L", "upperleg01.R", "lowerleg01.L", "lowerleg01.R")


def test_rest_pose_skins_to_the_rest_body(body_model):
    verts = body_model.default_verts("male")
    motion = rig_motion(body_model)
    assert np.array_equal(file_axes(motion), np.eye(3))  # Y up: taken as it is
    for method in ("lbs", "dqs"):
        posed = pose_body(body_model, verts, motion, method=method)
        assert np.abs(posed.verts - verts).max() < 1e-12 and posed.named == len(body_model.bone_names)


def test_a_bone_turns_about_its_own_joint_on_any_body(body_model):
    """The elbow bent 90 degrees on a tall body: the forearm turns about that body's elbow, lengths kept."""
    from vfit_engine.body.resolve import resolve_body

    body = resolve_body(body_model, targets={"height": 1.95}, gender="male")
    names = list(body_model.bone_names)
    motion = rig_motion(body_model, {"lowerarm01.L": (0.0, 0.0, 90.0)})
    _, rest = pose_matrices(body_model, body.verts, np.tile(np.eye(3), (len(names), 1, 1)))
    mats, posed = pose_matrices(body_model, body.verts, bone_rotations(body_model, motion))
    elbow, wrist = names.index("lowerarm01.L"), names.index("wrist.L")
    assert np.allclose(posed[elbow], rest[elbow], atol=1e-12)  # the parent chain did not move
    turn = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # 90 degrees about z (its Zrotation)
    assert np.allclose(posed[wrist] - posed[elbow], turn @ (rest[wrist] - rest[elbow]), atol=1e-12)
    assert np.allclose(mats[elbow, :, :3] @ rest[wrist] + mats[elbow, :, 3], posed[wrist])


@needs_poses
def test_makehuman_poses_are_z_up_and_name_every_bone(body_model):
    motion = read_bvh(POSES / "sit01.bvh")
    assert np.array_equal(file_axes(motion), Z_UP)
    assert set(body_model.bone_names) <= set(motion.names)


@needs_poses
@pytest.mark.parametrize("pose", ["sit01.bvh", "run01.bvh", "fight02.bvh"])
def test_a_pose_on_a_morphed_body_keeps_its_joints_inside_it(body_model, pose):
    from body_checks import winding_numbers
    from vfit_engine.body.resolve import resolve_body

    # a short pear-shaped woman of 60.3 kg with slim arms and thighs: the body this test built before the
    # population filled in what is not given (given only waist, hips and height it is now 67 kg; it passes
    # too, though fight02 then stretches 1 % of the edges beyond +69.5 %, near the bound below)
    body = resolve_body(body_model, targets={"waist": 0.84, "hips": 1.08, "height": 1.62, "upper-arm": 0.2325,
                                             "thigh": 0.537}, weight_kg=60.3, gender="female")
    posed = pose_body(body_model, body.verts, read_bvh(POSES / pose))
    n = 13380
    assert np.isfinite(posed.verts).all() and np.abs(posed.verts[:n] - body.verts[:n]).max() > 0.1
    joints = np.array([posed.heads[list(body_model.bone_names).index(j)] for j in CORE_JOINTS])
    # inside by winding number, not by the nearest skin's normal (MeshCollider.penetration): skinning lets
    # a posed body pass through itself, and sit01 rests the left forearm on the knee. On this body (and on
    # MakeHuman's own average woman) 60 forearm vertices sink into the knee; the nearest skin to the knee
    # joint is then the forearm's, 33 mm away and facing it, so the joint read "outside" though it is 43 mm
    # from its leg's skin, winding number 1.000. Measured: every core joint 1.000 in all three poses
    winding = winding_numbers(posed.verts[:n], body_model.body_tris, joints)
    assert (winding > 0.5).all(), dict(zip(CORE_JOINTS, np.round(winding, 2)))
    # edges keep their length where the skin is carried rigidly; skinning stretches the skin over a bent
    # knee or a raised shoulder (measured: 1 % of the edges beyond +65 % with fight02's arms overhead;
    # sit01 and run01 beyond +32 %), never tears it. A tear is bounded as a length, not a ratio: fight02's
    # most stretched edges, in the armpit crease, end 70-83 mm long on every woman of this size while their
    # rest length follows the build (edge 1339: 5.7 mm on MakeHuman's average woman, 11.8x; 12.1 mm on an
    # older morph's body for these targets, 5.9x; 14.8 mm at the heavy corner). Measured growth: 68 mm in
    # fight02, 36 in sit01, 22 in run01; a vertex carried by a wrong bone would move tens of cm
    e = body_model.body_tris[:, [0, 1]]
    rest = np.linalg.norm(body.verts[e[:, 0]] - body.verts[e[:, 1]], axis=1)
    length = np.linalg.norm(posed.verts[e[:, 0]] - posed.verts[e[:, 1]], axis=1)
    ratio = length / rest
    assert np.median(np.abs(ratio - 1)) < 0.01 and np.percentile(ratio, 99) < 1.7 and (length - rest).max() < 0.09


@needs_poses
def test_cli_pose(tmp_path):
    from vfit_engine.io.mesh import read_mesh

    out, js = tmp_path / "sit.obj", tmp_path / "sit.json"
    r = CliRunner().invoke(cli, ["pose", "--pose", str(POSES / "sit01.bvh"), "--gender", "male", "-o", str(out),
                                 "--json", str(js)])
    assert r.exit_code == 0, r.output
    mesh = read_mesh(str(out))
    assert mesh.n_verts == 13380 and "163 of the rig's 163 bones" in r.output
    import json

    rep = json.loads(js.read_text())
    assert rep["bones_posed"] == 163 and len(rep["joints"]) == 163 and rep["units"]["mesh"] == "m"


def test_cli_pose_bad_input(tmp_path):
    bad = tmp_path / "bad.bvh"
    bad.write_text("HIERARCHY\nROOT root\n{\n OFFSET 0 0 0\n CHANNELS 3 Xrotation Yrotation Wrotation\n}\n")
    for args, needle in ((["--pose", str(bad)], "bad.bvh"), (["--pose", str(tmp_path / "no.bvh")], "not found"),
                         (["--pose", str(bad), "-o", str(tmp_path / "x.stl")], "use one of")):
        r = CliRunner().invoke(cli, ["pose", *args])
        assert r.exit_code == 2 and needle in r.output and "Traceback" not in r.output, r.output
        assert r.output.count("\n") == 1


@needs_poses
def test_cli_pose_frame_out_of_range(tmp_path):
    r = CliRunner().invoke(cli, ["pose", "--pose", str(POSES / "sit01.bvh"), "--frame", "3", "-o",
                                 str(tmp_path / "x.obj")])
    assert r.exit_code == 2 and "the file has 1" in r.output and not (tmp_path / "x.obj").exists()
