"""Ease measured where it is defined (issue 33 section 2): a region's garment girth is the tape round the
garment's own loop round that body part in the body's plane -- the torso loop of a shirt, not its sleeves or
armholes; the sleeve round an arm, not the torso it joins -- and ease = garment - body."""
import numpy as np
import pytest

from test_fit import tube
from vfit_engine.fit.loops import garment_girth
from vfit_engine.io.meshdata import mesh_from_faces
from vfit_engine.section import MeshSections


def polygon_perimeter(p):
    return float(np.linalg.norm(np.roll(p, -1, axis=0) - p, axis=1).sum())


def circle(radius, n, centre=(0.0, 0.0)):
    a = 2.0 * np.pi * np.arange(n) / n
    return np.column_stack([centre[0] + radius * np.cos(a), centre[1] + radius * np.sin(a)])


def arc(radius, centre, a0, a1, n):
    a = np.linspace(a0, a1, n, endpoint=False)
    return np.column_stack([centre[0] + radius * np.cos(a), centre[1] + radius * np.sin(a)])


def torso_and_sleeves_outline(torso, sleeve, x_arm, n=400):
    """The outline (k, 2), counter-clockwise, of the union of a circle of radius ``torso`` round the origin and
    two of radius ``sleeve`` round (+-x_arm, 0) that overlap it: the torso's arc over the top, the left
    sleeve's outer arc, the torso's arc under the bottom, the right sleeve's outer arc."""
    xi = (x_arm ** 2 + torso ** 2 - sleeve ** 2) / (2 * x_arm)  # where the circles cross: (+-xi, +-zi)
    zi = np.sqrt(torso ** 2 - xi ** 2)
    t, s = np.arctan2(zi, xi), np.arctan2(zi, x_arm - xi)  # the crossing's angle round each centre
    return np.concatenate([arc(torso, (0, 0), t, np.pi - t, n), arc(sleeve, (-x_arm, 0), s, 2 * np.pi - s, n),
                           arc(torso, (0, 0), np.pi + t, 2 * np.pi - t, n),
                           arc(sleeve, (x_arm, 0), s - np.pi, np.pi - s, n)])


def test_a_tube_round_a_cylinder_has_the_ease_of_its_gap():
    """A garment tube of radius R round a body cylinder of radius r, both regular N-gons in line, cut by
    vfit's sections: the tape round each is its polygon (2 N R sin(pi / N)), and the ease their difference to
    1e-9 m; a tube stretched onto the skin with a 2 mm gap has an ease of 2 N (2 mm) sin(pi / N), 12.6 mm."""
    n = 48
    for gap in (0.002, 0.03):
        bverts, bfaces = tube(0.15, n, 5, 0.4, y0=-0.2)
        gverts, gfaces = tube(0.15 + gap, n, 9, 0.3, y0=-0.15)
        y = 0.013  # between vertex rows of both
        body = MeshSections(mesh_from_faces(bverts, bfaces).triangles(), len(bverts)).loops(bverts, y)
        cloth = MeshSections(mesh_from_faces(gverts, gfaces).triangles(), len(gverts)).loops(gverts, y)
        assert len(body) == 1 and len(cloth) == 1
        hull = garment_girth(cloth, (0.0, 0.0), body[0])
        girth = hull[1]
        assert girth == pytest.approx(2 * n * (0.15 + gap) * np.sin(np.pi / n), abs=1e-9)
        ease = girth - polygon_perimeter(body[0])
        assert ease == pytest.approx(2 * n * gap * np.sin(np.pi / n), abs=1e-9)
    assert 2 * n * 0.002 * np.sin(np.pi / n) == pytest.approx(0.01256, abs=1e-5)


# a torso of radius 15 cm with an arm of radius 5 cm on each side, 2 cm from it; a shirt's torso tube 1 cm
# off the skin and its sleeves 1.1 cm off the arms, their roots 1 mm into the tube (the armhole seams), cut
# where the plane runs through the armholes: one loop round the torso and both sleeves (the union's outline)
TORSO, ARM, X_ARM = 0.15, 0.05, 0.22
SHIRT = TORSO + 0.01
SLEEVE = X_ARM - SHIRT + 0.001


@pytest.fixture(scope="module")
def shirt_through_its_armholes():
    body_torso = circle(TORSO, 400)
    arms = [circle(ARM, 200, (x, 0.0)) for x in (-X_ARM, X_ARM)]
    outline = torso_and_sleeves_outline(SHIRT, SLEEVE, X_ARM)
    return body_torso, arms, outline


def test_a_shirts_chest_is_its_torso_loop_not_its_sleeves(shirt_through_its_armholes):
    """The chest of the shirt cut through its armholes is its torso tube's 2 pi R (to 1 mm: where a sleeve
    joins it, the tape bridges the seam), not the outline round the sleeves (69 cm more here) nor that
    outline cut to a band across the torso (the fit table before issue 33: the torso's half width + 3 cm,
    5.8 cm too much here)."""
    torso, arms, outline = shirt_through_its_armholes
    own = garment_girth([outline], (0.0, 0.0), torso, arms)
    assert own is not None
    assert own[1] == pytest.approx(2 * np.pi * SHIRT, abs=0.001)
    assert polygon_perimeter(outline) > 2 * np.pi * SHIRT + 0.3
    band = outline[np.abs(outline[:, 0]) <= TORSO + 0.03]
    assert garment_girth([band], (0.0, 0.0), torso)[1] > 2 * np.pi * SHIRT + 0.05
    # the ease of a shirt 1 cm off the skin: 2 pi (1 cm)
    assert own[1] - polygon_perimeter(torso) == pytest.approx(2 * np.pi * 0.01, abs=0.001)


def test_a_sleeve_is_its_own_loop_round_the_arm_not_the_torso_it_joins(shirt_through_its_armholes):
    """The same loop measured round the right arm: the sleeve's 2 pi r, to 1 mm (not the torso it joins)."""
    torso, arms, outline = shirt_through_its_armholes
    sleeve = garment_girth([outline], (X_ARM, 0.0), arms[1], [torso, arms[0]])
    assert sleeve[1] == pytest.approx(2 * np.pi * SLEEVE, abs=0.001)


def test_separate_sleeve_loops_beside_a_tube_leave_its_girth():
    """A tube with sleeve-like side tubes touching it in the plane, each its own loop: the tape is the
    tube's; a loop that does not go round the part (a sleeve beside the torso) is no part of it."""
    torso = circle(TORSO, 400)
    arms = [circle(ARM, 200, (x, 0.0)) for x in (-X_ARM, X_ARM)]
    r = X_ARM - SHIRT  # sleeves touching the tube
    loops = [circle(SHIRT, 300), circle(r, 150, (-X_ARM, 0.0)), circle(r, 150, (X_ARM, 0.0))]
    got = garment_girth(loops, (0.0, 0.0), torso, arms)
    # (to 10 um: where a sleeve touches the tube, the tube's points are as near the arm as the torso)
    assert got[1] == pytest.approx(polygon_perimeter(loops[0]), abs=1e-5)
    # no loop round the part: no tape
    assert garment_girth(loops[1:], (0.0, 0.0), torso, arms) is None


def test_the_girth_strain_is_the_stretch_along_the_tapes_line():
    """A tube stretched by e round its girth and by 20 % along its length: the strain along the tape's line
    is e (the cut steps are chords of the rings' triangles), its length as made the rest polygon's; a
    tube stretched only along its length is not stretched round the region. Half the tube bunched (its
    cloth shorter than made: a fold) and half stretched: the stretch is the taut half's, the garment's
    length as made the whole line's."""
    from vfit_engine.fit.loops import loop_strain
    from vfit_engine.fit.table import _Plane

    n = 40
    rest, faces = tube(0.15, n, 9, 0.4, y0=-0.2)
    tris = mesh_from_faces(rest, faces).triangles()
    plane = _Plane((0.0, 0.013, 0.0), (0.0, 1.0, 0.0))
    torso = circle(0.149, 400)
    for e in (0.0, 0.05, -0.02):
        pos = rest * np.array([1.0 + e, 1.2, 1.0 + e])
        strain, ratio = loop_strain(tris, rest, pos, plane, torso)
        assert strain == pytest.approx(e, abs=1e-9) and ratio == pytest.approx(1.0 + e, abs=1e-9)
    # radially 1 + 7 % cos(angle): the front stretched by up to 7 %, the back as much bunched; the whole
    # line as made as long as draped, the taut front's mean stretch 7 % 2 / pi = 4.5 %
    scale = 1.0 + 0.07 * rest[:, [2]] / 0.15
    strain, ratio = loop_strain(tris, rest, rest * np.hstack([scale, np.ones_like(scale), scale]), plane, torso)
    assert strain == pytest.approx(0.07 * 2 / np.pi, abs=0.003) and ratio == pytest.approx(1.0, abs=0.003)
    # with an arm beside it, the cloth nearer the arm is left out of both lengths (here none of it)
    assert loop_strain(tris, rest, rest * 1.05, plane, torso, [circle(0.05, 100, (0.5, 0.0))])[0] == \
        pytest.approx(0.05, abs=1e-9)


def test_a_loop_round_both_thighs_is_no_thigh_of_the_garment():
    """A skirt's hem goes round both thighs: no row for either (a trouser leg round one thigh keeps its row)."""
    from vfit_engine.fit.loops import round_together

    t = np.linspace(0, 2 * np.pi, 48, endpoint=False)
    circle = np.stack([np.cos(t), np.sin(t)], axis=1)
    left, right = 0.08 * circle + [-0.1, 0.0], 0.08 * circle + [0.1, 0.0]
    skirt = np.stack([0.25 * np.cos(t), 0.15 * np.sin(t)], axis=1)
    leg = 0.1 * circle + [-0.1, 0.0]
    assert round_together([skirt], [True], np.array([-0.1, 0.0]), [right])
    assert not round_together([leg], [True], np.array([-0.1, 0.0]), [right])
    assert not round_together([skirt], [False], np.array([-0.1, 0.0]), [right])  # an open chain goes round nothing
