"""Hostile input (issue 31, section 6, items 6 and 8): BVH files beyond the caps, .mhclo errors that name file and
line, a pose whose joints are no rig's, garments in the wrong units or flat, and messages that say true things.
Every input is synthetic, written to tmp_path; nothing here drapes cloth."""
import time
import warnings
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from click.testing import CliRunner

from vfit_cli.main import cli
from vfit_engine.errors import InputError
from vfit_engine.io.bvh import MAX_BVH_FRAMES, MAX_BVH_JOINTS, read_bvh

GARMENTS = Path(__file__).resolve().parents[2] / "shared" / "assets" / "garments"
HEAD = "HIERARCHY\nROOT r\n{\n OFFSET 0 0 0\n CHANNELS 3 Zrotation Xrotation Yrotation\n}\nMOTION\n"


def _error_lines(result):
    return [ln for ln in result.output.splitlines() if ln.startswith("Error")]


def _bvh(tmp_path, frames, declared=None, name="long.bvh", row=lambda f: f"{f % 7} {f % 5} 0"):
    """A one-joint BVH of ``frames`` frame lines (``declared`` in its Frames: line, default the same)."""
    p = tmp_path / name
    with open(p, "w") as fh:
        fh.write(HEAD + f"Frames: {frames if declared is None else declared}\nFrame Time: 0.01\n")
        fh.writelines(row(f) + "\n" for f in range(frames))
    return p


# --- 6: BVH files are read with limits ----------------------------------------------------------------------

def test_bvh_over_the_frame_cap_is_refused_at_its_header(tmp_path):
    """A file over the cap is refused in one line naming the file, its Frames: line, the count, the cap and the
    fix, before any frame is read (twice the cap, answered at once)."""
    p = _bvh(tmp_path, 2 * MAX_BVH_FRAMES)
    t0 = time.perf_counter()
    with pytest.raises(InputError) as info:
        read_bvh(p)
    msg = str(info.value)
    assert time.perf_counter() - t0 < 1.0
    assert msg.startswith(f"{p}:8: ") and f"'Frames: {2 * MAX_BVH_FRAMES}'" in msg and f"{MAX_BVH_FRAMES}" in msg
    assert "cut the motion" in msg and "\n" not in msg


def test_bvh_lying_frame_count_stops_at_the_cap(tmp_path):
    """'Frames: 1' over a flood of frame lines: counted up to the cap, not to the end of the file."""
    p = _bvh(tmp_path, 5000, declared=1)
    with pytest.raises(InputError, match=r":8: 'Frames: 1' but more than 100 frame lines follow; make them agree"):
        read_bvh(p, max_frames=100)
    with pytest.raises(InputError, match=r"'Frames: 1' but 5000 frame lines follow"):
        read_bvh(p)


def test_bvh_one_frame_of_a_long_file_keeps_one_frame(tmp_path):
    """``frame=k`` parses frame k only: the same values as a full read, a (1, c) array; the other lines are
    counted, not parsed (a garbled frame elsewhere does not stop it, as it stops a full read)."""
    p = _bvh(tmp_path, 2000, row=lambda f: "not numbers here" if f == 3 else f"{f} {f % 5} {-f}")
    one = read_bvh(p, frame=1234)
    assert one.frames.shape == (1, 3) and one.frames[0].tolist() == [1234, 4, -1234]
    with pytest.raises(InputError, match=":13: frame 4: 'not' is not a number"):
        read_bvh(p)
    with pytest.raises(InputError, match=r":8: frame 2000 asked for, the file has 2000; ask for one of 0\.\.1999"):
        read_bvh(p, frame=2000)


def test_bvh_joint_and_line_caps(tmp_path):
    joints = "".join(f"JOINT j{i}\n{{\nOFFSET 0 1 0\nCHANNELS 0\n" for i in range(MAX_BVH_JOINTS))
    p = tmp_path / "many.bvh"
    p.write_text("HIERARCHY\nROOT r\n{\nOFFSET 0 0 0\nCHANNELS 0\n" + joints + "}\n" * (MAX_BVH_JOINTS + 1))
    with pytest.raises(InputError, match=f"more than {MAX_BVH_JOINTS} joints"):
        read_bvh(p)
    p = tmp_path / "wide.bvh"
    p.write_text(HEAD + "Frames: 1\nFrame Time: 0.01\n" + "1 " * 600_000 + "\n")
    with pytest.raises(InputError, match=r":10: a line longer than 1048576 characters"):
        read_bvh(p)


def test_cli_pose_refuses_a_bvh_over_the_cap(tmp_path):
    p = _bvh(tmp_path, 0, declared=MAX_BVH_FRAMES + 1)
    out = tmp_path / "posed.obj"
    r = CliRunner().invoke(cli, ["pose", "--pose", str(p), "-o", str(out)])
    assert r.exit_code == 2 and "Traceback" not in r.output, r.output
    assert len(_error_lines(r)) == 1 and str(p) in r.output and f"{MAX_BVH_FRAMES}" in r.output
    assert not out.exists()


# --- 8: a pose whose joints are no rig's ------------------------------------------------------------------

ODD = ("HIERARCHY\nROOT root\n{\n OFFSET 0 0 0\n CHANNELS 3 Zrotation Xrotation Yrotation\n"
       " JOINT hand\n {\n  OFFSET 0 1 0\n  CHANNELS 3 Zrotation Xrotation Yrotation\n"
       "  End Site\n  {\n   OFFSET 0 1 0\n  }\n }\n}\nMOTION\nFrames: 1\nFrame Time: 0.1\n0 0 0 10 20 30\n")


def test_cli_pose_refuses_joints_that_map_to_no_bone(tmp_path):
    """vfit pose said 'posed 1 of 163 bones' and exited 0 with the body in its rest pose; vfit animate refused."""
    p = tmp_path / "odd.bvh"
    p.write_text(ODD)
    out = tmp_path / "posed.obj"
    r = CliRunner().invoke(cli, ["pose", "--pose", str(p), "-o", str(out)])
    assert r.exit_code == 2 and "Traceback" not in r.output and not out.exists(), r.output
    (line,) = _error_lines(r)
    assert str(p) in line and "1 are bones of the default rig (root)" in line and "hand is neither" in line
    assert "at least 10" in line and "--joint-map" in line


def test_animate_counts_root_as_the_rig_bone_it_is(body_model, tmp_path):
    """The shared check, from vfit animate's side: ``root`` is the rig's root bone, only ``hand`` is unknown."""
    from vfit_engine.animate.motion import load_clip

    p = tmp_path / "odd.bvh"
    p.write_text(ODD)
    with pytest.raises(InputError) as info:
        load_clip(body_model, str(p))
    msg = str(info.value)
    assert "1 are bones of the default rig (root), 0 are CMU names, and hand is neither" in msg
    assert "give --joint-map" in msg and "\n" not in msg


# --- 8: .mhclo errors name the file and the line -----------------------------------------------------------

MHCLO = ("# test\nname t\nobj_file t.obj\nx_scale 0 1 1.0\nverts 0\n{}\n"
         "10 11 12 0.2 0.3 0.5 0 0 0\n5\n")


@pytest.mark.parametrize("line, words", [
    ("99999 11 12 0.2 0.3 0.5 0 0 0", "body vertex 99999 is out of range, the hm08 base mesh has vertices 0..19157"),
    ("10 11 -3 0.2 0.3 0.5", "body vertex -3 is out of range"),
    ("10 11 12 nan 0.3 0.5 0 0 0", "weight or offset nan is not a finite number"),
    ("10 11 12 0.2 0.3 0.5 0 inf 0", "weight or offset inf is not a finite number"),
    ("10 11 twelve 0.2 0.3 0.5", "cannot read .mhclo line"),
])
def test_mhclo_errors_name_file_and_line(tmp_path, line, words):
    from vfit_engine.garment.mhclo import parse_mhclo

    p = tmp_path / "t.mhclo"
    p.write_text(MHCLO.format(line))
    with pytest.raises(InputError) as info:
        parse_mhclo(p)
    msg = str(info.value)
    assert msg.startswith(f"{p}:6: ") and words in msg and ";" in msg and "\n" not in msg, msg


@pytest.mark.parametrize("text, line, words", [
    (MHCLO.format("1 2 3 0.2 0.3 0.5").replace("x_scale 0 1 1.0", "x_scale 0 19158 1.0"), 4, "body vertex 19158"),
    (MHCLO.format("1 2 3 0.2 0.3 0.5").replace("x_scale 0 1 1.0", "x_scale 0 1 0"), 4, "not positive"),
    (MHCLO.format("1 2 3 0.2 0.3 0.5") + "delete_verts\n1 2 - 30000\n", 10, "body vertex 30000"),
    (MHCLO.format("1 2 3 0.2 0.3 0.5") + "delete_verts\n0 - 999999999999\n", 10, "body vertex 999999999999"),
])
def test_mhclo_scale_and_delete_lines_are_checked(tmp_path, text, line, words):
    from vfit_engine.garment.mhclo import parse_mhclo

    p = tmp_path / "t.mhclo"
    p.write_text(text)
    with pytest.raises(InputError, match=f"^{p}:{line}: .*{words}"):
        parse_mhclo(p)


def test_garment_with_a_bad_binding_warns_naming_file_and_line(tmp_path):
    """The drape ignores a binding it cannot use (and says so): the warning now says where the file is wrong."""
    from vfit_engine.garment.garment import load_garment

    v, f = _tube(0.15, 0.0, 0.6, 12, 4)
    obj = _write_obj(tmp_path / "g.obj", v, f)
    rows = ["0 1 2 0.2 0.3 0.5 0 0 0"] * len(v)
    rows[7] = "0 1 2 0.2 nan 0.5 0 0 0"
    (tmp_path / "g.mhclo").write_text("obj_file g.obj\nverts 0\n" + "\n".join(rows) + "\n")
    g = load_garment(obj, units="m")
    assert g.binding() is None
    assert any(f"{tmp_path / 'g.mhclo'}:10: weight or offset nan" in w for w in g.warnings), g.warnings


# --- 8: garments in the wrong units, or flat -----------------------------------------------------------------

def _tube(radius, y0, y1, around=16, rings=6):
    """An open cylinder (a skirt) about the Y axis: verts (n, 3), quads (m, 4) 1-based."""
    a = np.linspace(0, 2 * np.pi, around, endpoint=False)
    ys = np.linspace(y1, y0, rings)
    v = np.array([[radius * np.cos(t), y, radius * np.sin(t)] for y in ys for t in a])
    f = [[r * around + k + 1, r * around + (k + 1) % around + 1, (r + 1) * around + (k + 1) % around + 1,
          (r + 1) * around + k + 1] for r in range(rings - 1) for k in range(around)]
    return v, np.array(f)


def _write_obj(path, v, f):
    path.write_text("".join(f"v {x:.17g} {y:.17g} {z:.17g}\n" for x, y, z in v) + "".join(
        "f " + " ".join(map(str, q)) + "\n" for q in f))
    return path


def test_decimetre_garment_read_in_cm_warns(tmp_path):
    """A MakeHuman suit (dm, 12.9 units tall, 5 wide) read with --units cm is 13 cm tall: inside the height
    range, so it drew no warning and draped to 1,440 % strain. Now its size is questioned, naming the unit
    its height says; read in dm it warns nothing."""
    from vfit_engine.garment.garment import load_garment

    v, f = _tube(2.5, 0.0, 12.9)
    p = _write_obj(tmp_path / "suit.obj", v, f)
    g = load_garment(p, units="cm")
    assert g.units == "cm" and any("small for a garment" in w and "says dm" in w for w in g.warnings), g.warnings
    assert load_garment(p, units="dm").warnings == [] and load_garment(p).units == "dm"
    v, f = _tube(0.11, 0.0, 0.14)  # a cap 22 cm across, in m: said small, but drawn as asked
    assert load_garment(_write_obj(tmp_path / "cap.obj", v, f), units="m").units == "m"


@pytest.mark.skipif(not (GARMENTS / "female_casualsuit01").is_dir(), reason="../shared garments absent")
def test_shared_suit_read_in_cm_warns():
    from vfit_engine.garment.garment import load_garment

    path = GARMENTS / "female_casualsuit01" / "female_casualsuit01.obj"
    assert any("says dm" in w for w in load_garment(path, units="cm").warnings)
    assert load_garment(path).warnings == []


@pytest.mark.parametrize("units", ["auto", "m", "cm"])
def test_zero_height_garment_is_refused_before_numpy_warns(tmp_path, units):
    from vfit_engine.garment.garment import load_garment

    v, f = _tube(0.3, 0.0, 0.6)
    v[:, 1] = 0.25  # flat: a ring of quads in one horizontal plane
    p = _write_obj(tmp_path / "flat.obj", v, f)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a RuntimeWarning is a failure here
        with pytest.raises(InputError, match=r"garment has zero height \(every vertex at y = 0.25\); .*Y up"):
            load_garment(p, units=units)


def test_cli_drape_zero_height_is_one_line(tmp_path):
    v, f = _tube(0.3, 0.0, 0.6)
    v[:, 1] = 0.0
    p = _write_obj(tmp_path / "flat.obj", v, f)
    r = CliRunner().invoke(cli, ["drape", str(p), "--units", "m", "-o", str(tmp_path / "out")])
    assert r.exit_code == 2 and "Traceback" not in r.output and "RuntimeWarning" not in r.output, r.output
    assert len(_error_lines(r)) == 1 and "zero height" in r.output
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())  # nothing written


# --- 8: the fall message says what is true of the pins -------------------------------------------------------

@pytest.mark.parametrize("mode, dropped, words, absent", [
    ("auto", 3, "--pin auto held nothing (its 3 pin(s) lay inside the body and were let go); give a pin file",
     "use --pin auto"),
    ("file", 0, "the pin file held nothing; give a pin file", "use --pin auto"),
    ("none", 0, "nothing holds it up without pins; use --pin auto or a pin file", "held nothing"),
])
def test_fall_message_does_not_recommend_the_pins_in_use(capsys, mode, dropped, words, absent):
    """A single triangle under --pin auto lost its pins and fell: the message said 'use --pin auto'."""
    from vfit_cli.drape import _unsettled

    setup = SimpleNamespace(start=np.full((3, 3), 1.0), seams=np.zeros((0, 2), np.int64),
                            pins=SimpleNamespace(indices=np.zeros(0, np.int64),
                                                 info=dict(mode=mode, dropped_inside=dropped)))
    result = SimpleNamespace(pos=np.zeros((3, 3)), frames=40)
    assert _unsettled(setup, result, SimpleNamespace(), {}) == 3
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "slid 100 cm down the body in 40 frames" in err and words in err, err
    assert absent not in err


# --- 6: vfit animate poses only the frames it plays ------------------------------------------------------------

POSES = Path(__file__).resolve().parents[2] / "shared" / "assets" / "poses"


@pytest.mark.skipif(not (POSES / "sit01.bvh").is_file(), reason="../shared/assets/poses absent")
def test_clip_until_poses_only_what_is_played(body_model, tmp_path):
    """A 1,500-frame capture of the full rig (on a loaded 2-core machine: 44 s to load as a clip, 5.7 s, mostly
    the read, for its first 8 frames): ``until`` poses its first frames only, and the clip samples to the
    same bits up to ``until``, with the same duration and description as the whole clip's."""
    from vfit_engine.animate.motion import load_clip

    head, _, tail = (POSES / "sit01.bvh").read_text().partition("MOTION")
    row = np.array(tail.split()[5:], dtype=float)  # after 'Frames: 1 Frame Time: t'
    p = tmp_path / "long.bvh"
    p.write_text(head + "MOTION\nFrames: 1500\nFrame Time: 0.0333333\n"
                 + "".join(" ".join(f"{v:.6f}" for v in row + 0.01 * f) + "\n" for f in range(1500)))
    part = load_clip(body_model, str(p), until=0.2, travel=True)
    full = load_clip(body_model, str(p), travel=True)
    assert len(part.rotations) == 8 and len(full.rotations) == 1500  # frames 0..6 and the one after, at most
    assert part.duration == full.duration and part.description == full.description
    for t in np.linspace(0.0, 0.2, 13):
        for a, b in zip(part.sample(t, blend=0.7), full.sample(t, blend=0.7)):
            assert np.array_equal(a, b)
