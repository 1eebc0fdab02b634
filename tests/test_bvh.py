"""BVH reader/writer: MakeHuman poses, exact round trips, the rotation convention, FK, bad files."""
import itertools
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from vfit_engine.errors import InputError
from vfit_engine.io.bvh import Motion, read_bvh, write_bvh

POSES = Path(__file__).resolve().parents[2] / "shared" / "assets" / "poses"
POSE_FILES = sorted(POSES.glob("*.bvh"))
needs_poses = pytest.mark.skipif(not POSE_FILES, reason=f"no MakeHuman poses (*.bvh) in {POSES}")

ROT6 = ("Xposition", "Yposition", "Zposition", "Zrotation", "Yrotation", "Xrotation")
ZYX = ("Zrotation", "Yrotation", "Xrotation")


def _random_motion(seed=0, joints=12, frames=7):
    """A random depth-first tree: 6-channel root, 3-channel ZYX joints, End Sites on the leaves."""
    rng = np.random.default_rng(seed)
    parents, path = [-1], [0]  # path: ancestors of the last joint, itself included
    for i in range(1, joints):
        up = int(rng.integers(0, len(path)))  # attach below any ancestor: keeps the order depth-first
        path = path[: len(path) - up] + [i]
        parents.append(path[-2])
    leaves = sorted(set(range(joints)) - set(parents))
    return Motion(
        names=[f"j{i}" if i else "Hips" for i in range(joints)],
        parents=parents,
        offsets=rng.normal(size=(joints, 3)),
        channels=[ROT6] + [ZYX] * (joints - 1),
        end_sites={k: rng.normal(size=3) for k in leaves},
        frames=rng.uniform(-180, 180, size=(frames, 6 + 3 * (joints - 1))),
        frame_time=1 / 120,
    )


def _assert_same(a, b):
    assert a.names == b.names
    assert np.array_equal(a.parents, b.parents)
    assert np.array_equal(a.offsets, b.offsets)
    assert a.channels == b.channels
    assert a.end_sites.keys() == b.end_sites.keys()
    assert all(np.array_equal(a.end_sites[k], b.end_sites[k]) for k in a.end_sites)
    assert a.frames.shape == b.frames.shape and np.array_equal(a.frames, b.frames)
    assert a.frame_time == b.frame_time


def _write(tmp_path, text, name="m.bvh", newline="\n"):
    p = tmp_path / name
    p.write_bytes(text.replace("\n", newline).encode())
    return p


# --- the shared MakeHuman poses -----------------------------------------------------------------

@needs_poses
@pytest.mark.parametrize("path", POSE_FILES, ids=lambda p: p.name)
def test_makehuman_pose_parses(path):
    m = read_bvh(path)
    lines = [line.split() for line in path.read_text().splitlines()]
    assert len(m.names) == sum(t[:1] == ["JOINT"] for t in lines) + 1
    assert len(set(m.names)) == len(m.names)
    assert m.names[0] == "root" and m.parents[0] == -1 and np.all(m.parents[1:] < np.arange(1, len(m.names)))
    assert len(m.end_sites) == sum(t[:2] == ["End", "Site"] for t in lines)
    assert m.frames.shape == (1, sum(int(t[1]) for t in lines if t[:1] == ["CHANNELS"]))
    assert m.frames.shape[1] == sum(map(len, m.channels))
    # every OFFSET line, joints and End Sites alike, is somewhere in the result
    offs = np.array([[float(v) for v in t[1:]] for t in lines if t[:1] == ["OFFSET"]])
    got = np.vstack([m.offsets, *m.end_sites.values()])
    assert np.array_equal(np.sort(offs, axis=0), np.sort(got, axis=0))
    assert np.array_equal(m.frames[0], [float(v) for v in lines[-1]])
    g = m.global_transforms(0)
    assert np.all(np.isfinite(g))
    assert np.allclose(g[:, :3, :3] @ g[:, :3, :3].transpose(0, 2, 1), np.eye(3), atol=1e-12)


@needs_poses
def test_makehuman_pose_round_trip_is_exact(tmp_path):
    m = read_bvh(POSE_FILES[0])
    write_bvh(tmp_path / "copy.bvh", m)
    _assert_same(m, read_bvh(tmp_path / "copy.bvh"))
    assert [p.name for p in tmp_path.iterdir()] == ["copy.bvh"]  # atomic write left no temp file


# --- round trip and tolerant reading ------------------------------------------------------------

def test_synthetic_multi_frame_round_trip(tmp_path):
    m = _random_motion(seed=1)
    assert len(set(m.parents.tolist())) > 2  # a branching tree, not a chain
    p = tmp_path / "zyx.bvh"
    write_bvh(p, m)
    r = read_bvh(p)
    _assert_same(m, r)
    write_bvh(tmp_path / "again.bvh", r)
    assert (tmp_path / "again.bvh").read_bytes() == p.read_bytes()


def test_write_refuses_non_depth_first_order_and_nan(tmp_path):
    m = Motion(["a", "b", "c", "d"], [-1, 0, 0, 1], np.zeros((4, 3)), [("Xrotation",)] * 4, frames=[[0] * 4])
    with pytest.raises(ValueError, match="depth-first"):
        write_bvh(tmp_path / "x.bvh", m)  # d (child of b) after c: would read back as c's child
    m = _random_motion(seed=2)
    m.frames[3, 5] = np.nan
    with pytest.raises(InputError, match="NaN"):
        write_bvh(tmp_path / "x.bvh", m)
    assert not list(tmp_path.iterdir())


CMU_LIKE = """HIERARCHY
ROOT Hips
{
  OFFSET 0.0 0.0 0.0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation
  JOINT LeftUpLeg {
\tOFFSET 1.5 -2 0
\tCHANNELS 3 Zrotation Yrotation Xrotation
\tEnd Site
\t{
\t\tOFFSET 0 -4 0
\t}
  }
\tJOINT Spine
\t{
\t\tOFFSET 0 2 0
\t\tCHANNELS 3 zrotation XROTATION Yrotation
\t}
}

MOTION
Frames:\t2
Frame Time: 0.008333
1 2 3 10 20 30 40 50 60 70 80 90
-1\t-2 -3 -10 -20 -30 -40 -50 -60 -70 -80 -90

"""


@pytest.mark.parametrize("newline", ["\n", "\r\n", "\r"])
def test_generic_bvh_tabs_braces_and_line_ends(tmp_path, newline):
    m = read_bvh(_write(tmp_path, "\ufeff" + CMU_LIKE, newline=newline))
    assert m.names == ["Hips", "LeftUpLeg", "Spine"]
    assert m.parents.tolist() == [-1, 0, 0]
    assert m.channels[2] == ("Zrotation", "Xrotation", "Yrotation")  # spelled canonically
    assert m.offsets.tolist() == [[0, 0, 0], [1.5, -2, 0], [0, 2, 0]]
    assert list(m.end_sites) == [1] and m.end_sites[1].tolist() == [0, -4, 0]
    assert m.frames.shape == (2, 12) and m.frames[1, 11] == -90 and m.frame_time == 0.008333
    assert [(s.start, s.stop) for s in m.channel_slices()] == [(0, 6), (6, 9), (9, 12)]
    assert np.allclose(m.local_translations(1), [[-1, -2, -3], [1.5, -2, 0], [0, 2, 0]])


def test_zero_frames(tmp_path):
    text = CMU_LIKE.split("MOTION")[0] + "MOTION\nFrames: 0\nFrame Time: 0.033333\n"
    m = read_bvh(_write(tmp_path, text))
    assert m.frames.shape == (0, 12)
    write_bvh(tmp_path / "out.bvh", m)
    _assert_same(m, read_bvh(tmp_path / "out.bvh"))


# --- conventions ---------------------------------------------------------------------------------

@pytest.mark.parametrize("order", ["".join(p) for p in itertools.permutations("XYZ")])
def test_rotation_matches_scipy_intrinsic_euler(order):
    rng = np.random.default_rng(sum(map(ord, order)))
    angles = rng.uniform(-180, 180, size=(20, 3))
    ch = tuple(f"{a}rotation" for a in order)
    m = Motion([f"j{i}" for i in range(20)], np.arange(20) - 1, np.zeros((20, 3)), [ch] * 20, frames=[angles.ravel()])
    got = m.local_rotations(0)
    assert np.allclose(got, Rotation.from_euler(order, angles, degrees=True).as_matrix(), atol=1e-12)
    # and not the extrinsic (lowercase) composition, which differs for general angles
    assert not np.allclose(got, Rotation.from_euler(order.lower(), angles, degrees=True).as_matrix())


def test_rotation_order_and_direction_by_hand():
    """Zrotation 90 then Xrotation 90: R = Rz @ Rx takes +Z to -Y (Rx), then -Y to +X (Rz)."""
    m = Motion(["a", "b"], [-1, 0], np.zeros((2, 3)),
               [("Zrotation", "Xrotation"), ("Xrotation", "Zrotation")], frames=[[90, 90, 90, 90]])
    r = m.local_rotations(0)
    assert np.allclose(r[0] @ [0, 0, 1], [1, 0, 0])
    assert np.allclose(r[1] @ [0, 0, 1], [0, -1, 0])  # Rx @ Rz: Rz keeps +Z, Rx turns it to -Y


def test_missing_and_single_channels_are_identity():
    m = Motion(["a", "b", "c"], [-1, 0, 1], [[0, 0, 0], [1, 0, 0], [0, 1, 0]],
               [("Zposition",), (), ("Yrotation",)], frames=[[5.0, 30.0]])
    assert np.allclose(m.local_translations(0), [[0, 0, 5], [1, 0, 0], [0, 1, 0]])
    r = m.local_rotations(0)
    assert np.allclose(r[:2], np.eye(3))
    assert np.allclose(r[2], Rotation.from_euler("Y", 30, degrees=True).as_matrix())


FK_CHAIN = """HIERARCHY
ROOT base
{
\tOFFSET 1 2 3
\tCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
\tJOINT mid
\t{
\t\tOFFSET 0 1 0
\t\tCHANNELS 3 Zrotation Xrotation Yrotation
\t\tJOINT tip
\t\t{
\t\t\tOFFSET 0 2 0
\t\t\tCHANNELS 3 Zrotation Xrotation Yrotation
\t\t\tEnd Site
\t\t\t{
\t\t\t\tOFFSET 0 0.5 0
\t\t\t}
\t\t}
\t}
}
MOTION
Frames: 2
Frame Time: 0.04
10 0 0 0 0 0 90 0 0 0 0 0
0 0 0 0 0 90 90 0 0 0 0 0
"""


def test_forward_kinematics_three_joint_chain(tmp_path):
    m = read_bvh(_write(tmp_path, FK_CHAIN))
    assert np.allclose(m.rest_positions(), [[1, 2, 3], [1, 3, 3], [1, 5, 3]])
    # frame 0: root moved +10 in X; mid turns 90 deg about Z, so its child offset (0, 2, 0) -> (-2, 0, 0)
    g = m.global_transforms(0)
    assert np.allclose(g[:, :3, 3], [[11, 2, 3], [11, 3, 3], [9, 3, 3]])
    assert np.allclose(g[2, :3, :3], [[0, -1, 0], [1, 0, 0], [0, 0, 1]])
    # frame 1: also the root turns 90 deg about Y (x -> -z, z -> x); then mid's turn about Z:
    # mid = (1,2,3) + Ry (0,1,0) = (1,3,3); tip = mid + Ry Rz (0,2,0) = mid + Ry (-2,0,0) = (1,3,5)
    g = m.global_transforms(1)
    assert np.allclose(g[:, :3, 3], [[1, 2, 3], [1, 3, 3], [1, 3, 5]])
    # the End Site: Rz turns (0, 0.5, 0) to (-0.5, 0, 0), Ry turns that to (0, 0, 0.5)
    assert np.allclose(g[2] @ [*m.end_sites[2], 1], [1, 3, 5.5, 1])


# --- bad files -----------------------------------------------------------------------------------

GOOD = ("HIERARCHY\nROOT r\n{\n OFFSET 0 0 0\n CHANNELS 3 Xrotation Yrotation Zrotation\n}\n"
        "MOTION\nFrames: 1\nFrame Time: 0.1\n1 2 3\n")  # the BAD cases below each break one thing

BAD = {  # name: (file text, line the message must name, words it must contain)
    "not_bvh": ("hello world\nROOT x\n", 1, "not a BVH file"),
    "empty_file": ("", 1, "not a BVH file"),
    "empty_hierarchy": ("HIERARCHY\nMOTION\nFrames: 0\nFrame Time: 0.1\n", 2, "empty hierarchy"),
    "no_root": ("HIERARCHY\nJOINT a\n{\n}\nMOTION\n", 2, "ROOT"),
    "two_roots": (GOOD.replace("MOTION", "ROOT s\n{\n OFFSET 0 0 0\n CHANNELS 0\n}\nMOTION"), 7, "ROOT"),
    "unclosed_brace": (GOOD.replace("}\nMOTION", "MOTION"), 6, "unbalanced braces"),
    "extra_brace": (GOOD.replace("}\nMOTION", "}\n}\nMOTION"), 7, "unbalanced braces"),
    "never_closed": ("HIERARCHY\nROOT r\n{\n OFFSET 0 0 0\n", 4, "unbalanced braces"),
    "no_open_brace": (GOOD.replace("ROOT r\n{", "ROOT r\n OFFSET 0 0 0"), 3, "expected '{'"),
    "unknown_channel": (GOOD.replace("Yrotation", "Wrotation"), 5, "'Wrotation'"),
    "repeated_channel": (GOOD.replace("Yrotation", "Xrotation"), 5, "repeated channel"),
    "channel_count": (GOOD.replace("CHANNELS 3", "CHANNELS 4"), 5, "CHANNELS says 4"),
    "short_offset": (GOOD.replace("OFFSET 0 0 0", "OFFSET 0 0"), 4, "OFFSET needs 3 numbers"),
    "no_offset": (GOOD.replace(" OFFSET 0 0 0\n", ""), 5, "OFFSET"),
    "unknown_keyword": (GOOD.replace("CHANNELS", "CHANELS"), 5, "unknown keyword 'CHANELS'"),
    "too_few_values": (GOOD.replace("1 2 3", "1 2"), 10, "expected 3 values (one per channel), got 2"),
    "too_many_values": (GOOD.replace("1 2 3", "1 2 3 4"), 10, "expected 3 values (one per channel), got 4"),
    "nan_value": (GOOD.replace("1 2 3", "1 nan 3"), 10, "'nan' (value 2) is not finite"),
    "inf_offset": (GOOD.replace("OFFSET 0 0 0", "OFFSET 0 inf 0"), 4, "'inf' (value 2) is not finite"),
    "not_a_number": (GOOD.replace("1 2 3", "1 two 3"), 10, "'two' is not a number"),
    "frames_too_many": (GOOD.replace("Frames: 1", "Frames: 2"), 8, "'Frames: 2' but 1 frame lines"),
    "extra_frame_line": (GOOD + "4 5 6\n", 8, "'Frames: 1' but 2 frame lines"),
    "frames_not_int": (GOOD.replace("Frames: 1", "Frames: 1.5"), 8, "not a whole number"),
    "no_frame_time": (GOOD.replace("Frame Time: 0.1\n", ""), 9, "Frame Time"),
    "end_site_outside": ("HIERARCHY\nEnd Site\n{\n}\n", 2, "End Site"),
    "no_motion": (GOOD.split("MOTION")[0], 6, "no MOTION"),
    "duplicate_name": (GOOD.replace("}\nMOTION", " JOINT r\n {\n OFFSET 0 0 0\n CHANNELS 0\n }\n}\nMOTION"), 6,
                       "already named on line 2"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_file_gives_one_line_input_error(tmp_path, case):
    text, line, words = BAD[case]
    p = _write(tmp_path, text, name=f"{case}.bvh")
    with pytest.raises(InputError) as info:
        read_bvh(p)
    msg = str(info.value)
    assert msg.startswith(f"{p}:{line}: "), msg
    assert words in msg and "\n" not in msg
    assert ";" in msg  # what is wrong; then how to fix it


def test_missing_file_and_good_reference(tmp_path):
    assert read_bvh(_write(tmp_path, GOOD)).frames.tolist() == [[1, 2, 3]]  # the BAD cases break a good file
    with pytest.raises(InputError, match=r"nothere\.bvh: cannot read the file .*check the path"):
        read_bvh(tmp_path / "nothere.bvh")
