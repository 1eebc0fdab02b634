"""The built-in walk: its curves, its loop, and the angles a posed skeleton actually shows."""
import numpy as np
import pytest
from click.testing import CliRunner

from vfit_cli.main import cli
from vfit_engine.body.gait import (ANKLE_DORSIFLEXION, HIP_FLEXION, KNEE_FLEXION, curve, rest_angles, stride_time,
                                   walk_motion)
from vfit_engine.body.pose import bone_rotations, pose_matrices
from vfit_engine.body.segment import bone_positions
from vfit_engine.errors import InputError


def test_curves_pass_their_key_points_and_loop():
    for points in (HIP_FLEXION, KNEE_FLEXION, ANKLE_DORSIFLEXION):
        x, y = np.array(points, dtype=float).T
        assert np.allclose(curve(points, x / 100.0), y, atol=1e-9)
        assert np.isclose(curve(points, 0.25), curve(points, 1.25))
    knee = curve(KNEE_FLEXION, np.linspace(0, 1, 1001))
    assert 60 < knee.max() < 66 and 0.68 < np.argmax(knee) / 1000 < 0.76  # peak swing flexion ~62 deg at ~72 %


def test_cadence_sets_the_stride_time():
    assert np.isclose(stride_time(1.0), 1.2) and np.isclose(stride_time(1.6), 1.0)  # 100 and 120 steps/min
    assert stride_time(2.5) == pytest.approx(120 / 130)  # clamped
    with pytest.raises(InputError, match="not a walk"):
        walk_motion(None, speed=4.0)


def _sagittal(v):
    return np.degrees(np.arctan2(v[2], -v[1]))


@pytest.mark.parametrize("gender", ["female", "male"])
def test_a_posed_skeleton_walks_as_the_curves_say(body_model, gender):
    """Hip and knee flexion measured on the posed joints of a body equal the published curves (+-2 deg: the
    pelvis's tilt and rotation move the projection a little), the left side half a stride later."""
    motion = walk_motion(body_model, speed=1.3, fps=30, cycles=2)
    n = len(motion.frames) // 2
    assert np.allclose(motion.frames[:n], motion.frames[n:])  # loops
    verts = body_model.default_verts(gender)
    names = list(body_model.bone_names)
    rest = rest_angles(bone_positions(body_model, body_model.default_verts("female")))
    assert 30 < rest["lowerarm01"] < 45 and rest["upperleg01"] < 8  # MakeHuman's A pose: elbows bent, legs straight
    for k in range(0, n, 4):
        _, heads = pose_matrices(body_model, verts, bone_rotations(body_model, motion, k))
        phase = k / n
        for side, shift in (("R", 0.0), ("L", 0.5)):
            hip, knee, ankle = (heads[names.index(f"{b}.{side}")] for b in ("upperleg01", "lowerleg01", "foot"))
            thigh, shank = _sagittal(knee - hip), _sagittal(ankle - knee)
            want_hip = curve(HIP_FLEXION, phase - shift)
            want_knee = curve(KNEE_FLEXION, phase - shift)
            assert abs(thigh - want_hip) < 2.5, (gender, k, side, thigh, want_hip)
            assert abs((thigh - shank) - want_knee) < 2.5, (gender, k, side, thigh - shank, want_knee)


def test_cli_walk(tmp_path):
    from PIL import Image

    out, gif = tmp_path / "step.obj", tmp_path / "walk.gif"
    r = CliRunner().invoke(cli, ["pose", "--pose", "walk", "--speed", "1.6", "--frame", "7", "-o", str(out),
                                 "--gif", str(gif)])
    assert r.exit_code == 0, r.output
    assert out.is_file() and Image.open(gif).n_frames == 30  # 1.0 s per stride at 1.6 m/s, 30 frames/s
    r = CliRunner().invoke(cli, ["pose", "--pose", "walk", "--frame", "99", "-o", str(tmp_path / "x.obj")])
    assert r.exit_code == 2 and "the walk has 33" in r.output
