"""Garment openings against the body part they go round (a cylinder 'arm' with a tube 'sleeve')."""
import math
from pathlib import Path

import numpy as np
import pytest
import trimesh

from vfit_engine.garment.openings import check_openings
from vfit_engine.sim.springs import grid_polygons
from vfit_engine.geometry import closed_loops
from vfit_engine.io.meshdata import mesh_from_faces

GARMENTS = Path(__file__).resolve().parents[1] / ".." / "shared" / "assets" / "garments"


def tube(radius, around=48, rows=3, height=0.06, tilt=0.0):
    """An open quad tube round the y axis (two boundary loops), optionally tilted about z."""
    a = 2 * math.pi * np.arange(around) / around
    ys = np.linspace(-height / 2, height / 2, rows)
    pos = np.array([[radius * math.cos(t), y, radius * math.sin(t)] for y in ys for t in a])
    c, s = math.cos(tilt), math.sin(tilt)
    pos = pos @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]).T
    faces = [[r * around + i, r * around + (i + 1) % around, (r + 1) * around + (i + 1) % around,
              (r + 1) * around + i] for r in range(rows - 1) for i in range(around)]
    return mesh_from_faces(pos, faces)


@pytest.fixture(scope="module")
def arm():
    m = trimesh.creation.cylinder(radius=0.05, height=0.5, sections=128)  # along z
    turn = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])  # a rotation taking it along y
    return np.asarray(m.vertices, dtype=np.float64) @ turn.T, np.asarray(m.faces, dtype=np.int64)


def test_closed_loops_of_a_grid_and_a_tube():
    pos, fv, fo = grid_polygons(5, 4)
    sizes = np.diff(fo)
    (loop,) = closed_loops(mesh_from_faces(pos, fv.reshape(-1, 4)))
    assert np.all(sizes == 4) and loop.size == 2 * (5 + 4) - 4
    assert sorted(len(lp) for lp in closed_loops(tube(0.04))) == [48, 48]


@pytest.mark.parametrize("radius, tilt", [(0.045, 0.0), (0.045, 0.3), (0.06, 0.0)])
def test_sleeve_on_a_cylinder(arm, radius, tilt):
    verts, tris = arm
    found = check_openings(tube(radius, tilt=tilt), verts, tris, skin=0.002)
    assert len(found) == 2
    length = 48 * 2 * radius * math.sin(math.pi / 48)
    # the fitted plane is perpendicular to the tilted tube: the arm's section there is an ellipse,
    # whose smallest tape over the plane offsets is still >= the straight section's
    for o in found:
        assert o["rest_length_mm"] == pytest.approx(1000 * length, rel=1e-9)
        assert o["body_tape_mm"] >= 1000 * 2 * 128 * 0.05 * math.sin(math.pi / 128) * (1 - 1e-9)
        if tilt == 0:
            assert o["body_tape_mm"] == pytest.approx(1000 * 2 * 128 * 0.05 * math.sin(math.pi / 128), rel=1e-6)
            need = (2 * 128 * 0.05 * math.sin(math.pi / 128) + 2 * math.pi * 0.002) / length - 1
            assert o["required_strain"] == pytest.approx(need, rel=1e-6)
        assert (o["required_strain"] > 0) == (radius < 0.05)


@pytest.mark.skipif(not GARMENTS.is_dir(), reason="../shared not present")
def test_female_suit_sleeves_are_smaller_than_the_arm(body_model):
    """The measurement behind the female suits' drape results: their short-sleeve hems must stretch
    more than the 10 % strain bar on the default female body, whatever the drape does."""
    from vfit_engine.body.model import N_BODY
    from vfit_engine.garment.garment import load_garment

    body = body_model.default_verts("female")[:N_BODY]
    for name in ("female_casualsuit01", "female_sportsuit01"):
        g = load_garment(GARMENTS / name / f"{name}.obj")
        found = check_openings(g.mesh, body, body_model.body_tris)
        tight = [o for o in found if o["required_strain"] > 0]
        assert len(tight) == 2 and all(o["vertices"] == 21 for o in tight)  # the two sleeve hems
        assert min(o["required_strain"] for o in tight) > 0.10
        assert all(abs(abs(o["centre_m"][0]) - 0.24) < 0.01 for o in tight)  # at the upper arms


def test_the_body_tape_at_the_openings_own_place_on_a_cone():
    """On a cone (radius 5 cm at y = 0, 0.5 mm less per mm up) a cuff's tape at its own place is the cone's
    section there, and the smallest within the offsets the one 3 cm above: at most the tape at its place, so an
    opening the body forces wider (``required_strain`` > 0) is never longer as made than the body at its place
    plus the skin's 2 pi gap (the table's rule never reads its stretch as 0)."""
    m = trimesh.creation.cone(radius=0.15, height=0.3, sections=256)  # apex up the z axis, base at z = 0
    turn = np.array([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]])  # z up -> y up
    verts = np.asarray(m.vertices, dtype=np.float64) @ turn.T - [0.0, 0.2, 0.0]  # radius 5 cm at y = 0
    tris = np.asarray(m.faces, dtype=np.int64)
    radius_at = lambda y: 0.15 * (0.1 - y) / 0.3  # noqa: E731
    chord = 2 * 256 * math.sin(math.pi / 256)
    for y0, r in ((0.0, 0.045), (0.03, 0.04)):  # a cuff the cone forces wider at its lower loop, one it does not
        cuff = tube(r).with_verts(tube(r).verts + [0.0, y0, 0.0])
        found = check_openings(cuff, verts, tris, skin=0.002)
        assert len(found) == 2
        for o in found:
            y = o["centre_m"][1]
            assert o["body_tape_here_mm"] == pytest.approx(1000 * chord * radius_at(y), rel=1e-3)
            assert o["body_tape_mm"] == pytest.approx(1000 * chord * radius_at(y + 0.03), rel=1e-3)
            if o["required_strain"] > 0:
                assert o["rest_length_mm"] < o["body_tape_here_mm"] + 1000 * 2 * math.pi * 0.002


def test_a_sewn_tube_has_the_openings_of_the_garment_not_of_its_panels(arm):
    """Two flat panels 20 cm wide, sewn along both sides round the arm (a seam's two sides two vertices, as a sewn
    pattern's cloth keeps them): with the weld, two openings of 40 cm as made (the panels' widths summed, from
    their flat lengths); without it, only the panels' outlines, none of which goes round the arm."""
    from vfit_engine.pattern.weld import sewn_to

    verts, tris = arm
    around, rows = 24, 3  # each panel: 13 columns (12 quads) x 3 rows
    cols = around // 2 + 1
    rest, placed, faces = [], [], []
    for panel in range(2):
        for r, y in enumerate(np.linspace(-0.03, 0.03, rows)):
            for c in range(cols):
                rest.append([0.3 * panel + 0.2 * c / (cols - 1), y, 0.0])  # flat, the panels apart
                t = math.pi * (panel + c / (cols - 1))
                placed.append([0.0636 * math.cos(t), y, 0.0636 * math.sin(t)])  # round the arm: 40 cm round
        base = panel * rows * cols
        faces += [[base + r * cols + c, base + r * cols + c + 1, base + (r + 1) * cols + c + 1,
                   base + (r + 1) * cols + c] for r in range(rows - 1) for c in range(cols - 1)]
    # the seams: panel 0's last column to panel 1's first, panel 1's last to panel 0's first
    pairs = [[r * cols + cols - 1, rows * cols + r * cols] for r in range(rows)]
    pairs += [[rows * cols + r * cols + cols - 1, r * cols] for r in range(rows)]
    mesh = mesh_from_faces(np.array(rest), faces)
    placed = np.array(placed)
    assert check_openings(mesh, verts, tris, pos=placed) == []
    found = check_openings(mesh, verts, tris, pos=placed, weld=sewn_to(len(rest), pairs))
    assert len(found) == 2
    for o in found:
        assert o["rest_length_mm"] == pytest.approx(400.0, rel=1e-9)
        assert o["body_tape_mm"] == pytest.approx(1000 * 2 * math.pi * 0.05, rel=0.01)
