"""Grading a sewing pattern (vfit_engine.pattern.grade): the girth rule on analytic tubes, stitched edges that
still match, the GarmentCode shirt graded up and down, and the body a pattern was made for."""
from pathlib import Path

import numpy as np
import pytest

from vfit_engine.errors import InputError
from vfit_engine.pattern.grade import grade, made_for, stitch_drift
from vfit_engine.pattern.model import Edge, EdgeRef, Panel, Pattern, Stitch

PATTERNS = Path(__file__).resolve().parents[2] / "shared" / "assets" / "patterns"
needs_shared = pytest.mark.skipif(not PATTERNS.is_dir(), reason="../shared/assets/patterns absent")


def tube(width=0.5, height=0.6):
    """Two rectangles (front and back, ``width`` x ``height`` m) sewn along both sides into a tube of girth
    2 * width; a panel's own y is its height on the body."""
    v = np.array([[0, 0], [width, 0], [width, height], [0, height]], float)
    loop = [Edge(i, (i + 1) % 4) for i in range(4)]
    panels = {n: Panel(n, v.copy(), list(loop)) for n in ("torso_front", "torso_back")}
    stitches = [Stitch(EdgeRef("torso_front", 1), EdgeRef("torso_back", 3)),
                Stitch(EdgeRef("torso_front", 3), EdgeRef("torso_back", 1))]
    return Pattern(panels, stitches, source="tube")


def own_height(pattern):
    return lambda name, xy: np.asarray(xy)[:, 1]


def girth_at(pattern, y):
    """The tube's girth (m) at height ``y``: each panel's width there, from its graded outline, summed."""
    total = 0.0
    for p in pattern.panels.values():
        poly = p.outline(61)  # (no sample exactly at a tested height)
        f = poly[:, 1] - y
        g = np.roll(f, -1)
        hit = f * g < 0
        t = f[hit] / (f[hit] - g[hit])
        x = np.sort(poly[hit, 0] + t * (np.roll(poly[:, 0], -1)[hit] - poly[hit, 0]))
        total += float(x[1::2].sum() - x[::2].sum())
    return total


def test_a_tube_graded_by_d_grows_by_d_at_every_height():
    pat = tube()
    g = grade(pat, own_height(pat), {"waist": (0.3, 0.9, 0.06)})
    for y in (0.05, 0.3, 0.55):  # one level: the same scale all the way up and down
        assert girth_at(g.pattern, y) == pytest.approx(1.06, abs=1e-4)
    assert g.levels["waist"]["garment_cm"] == pytest.approx(100.0)
    assert g.levels["waist"]["scale"] == pytest.approx(1.06)
    # the side seams are still the tube's height and match
    assert np.abs(stitch_drift(pat, g.pattern)).max() < 1e-6
    assert g.pattern.edge_length(EdgeRef("torso_front", 1)) == pytest.approx(0.6, abs=1e-6)
    # the pattern given is not changed
    assert girth_at(pat, 0.3) == pytest.approx(1.0, abs=1e-6)


def test_between_two_levels_the_growth_is_linear_in_height_and_constant_beyond():
    pat = tube()
    levels = {"bust": (0.5, 0.9, 0.08), "hips": (0.1, 0.95, 0.02)}
    g = grade(pat, own_height(pat), levels)
    assert girth_at(g.pattern, 0.5) == pytest.approx(1.08, abs=5e-4)
    assert girth_at(g.pattern, 0.1) == pytest.approx(1.02, abs=5e-4)
    assert girth_at(g.pattern, 0.2) == pytest.approx(1.035, abs=5e-4)  # a quarter of the way up
    assert girth_at(g.pattern, 0.58) == pytest.approx(1.08, abs=5e-4)  # above the highest level
    assert girth_at(g.pattern, 0.02) == pytest.approx(1.02, abs=5e-4)  # below the lowest
    # the side seams bend the same way on both panels: still equal
    assert np.abs(stitch_drift(pat, g.pattern)).max() < 2e-4


def test_a_level_the_garment_does_not_go_round_is_left_out():
    pat = tube()
    # a body 2.5 m round at 0.5: the tube (1 m) crosses that height but cannot be going round that body there
    g = grade(pat, own_height(pat), {"waist": (0.3, 0.9, 0.06), "bust": (0.5, 2.5, 0.5)})
    assert set(g.levels) == {"waist"}
    with pytest.raises(InputError, match="no panel crosses"):
        grade(pat, own_height(pat), {"bust": (0.8, 0.9, 0.05)})


def test_a_change_beyond_one_pattern_is_refused():
    pat = tube()
    with pytest.raises(InputError, match="beyond what one pattern grades to"):
        grade(pat, own_height(pat), {"waist": (0.3, 0.9, -0.6)})


def sleeve_pattern():
    """A trunk tube with a sleeve of two halves: each half's cap (a slanted edge) sewn to a slanted armhole
    edge of equal length in the torso's top corner."""
    w, h = 0.5, 0.6
    torso = np.array([[0, 0], [w, 0], [w, 0.4], [w - 0.1, h], [0, h]], float)
    loop5 = [Edge(i, (i + 1) % 5) for i in range(5)]
    armhole = float(np.hypot(0.1, 0.2))
    # a sleeve half in its own frame: x across the arm (0 .. 0.2), y along it (0 at the cuff, up to the cap)
    cap_rise = float(np.sqrt(armhole ** 2 - 0.2 ** 2)) if armhole > 0.2 else 0.05
    sl = np.array([[0, 0], [0.2, 0], [0.2, 0.3], [0, 0.3 + cap_rise]], float)
    loop4 = [Edge(i, (i + 1) % 4) for i in range(4)]
    panels = {"torso_front": Panel("torso_front", torso.copy(), list(loop5)),
              "torso_back": Panel("torso_back", torso.copy(), list(loop5)),
              "sleeve_front": Panel("sleeve_front", sl.copy(), list(loop4)),
              "sleeve_back": Panel("sleeve_back", sl.copy(), list(loop4))}
    st = [Stitch(EdgeRef("torso_front", 4), EdgeRef("torso_back", 4)),
          Stitch(EdgeRef("torso_front", 1), EdgeRef("torso_back", 1)),  # (a panel edge sewn once each)
          Stitch(EdgeRef("sleeve_front", 2), EdgeRef("torso_front", 2)),
          Stitch(EdgeRef("sleeve_back", 2), EdgeRef("torso_back", 2)),
          Stitch(EdgeRef("sleeve_front", 1), EdgeRef("sleeve_back", 1)),
          Stitch(EdgeRef("sleeve_front", 3), EdgeRef("sleeve_back", 3))]
    return Pattern(panels, st, source="sleeved")


def test_a_sleeve_grows_with_the_arm_and_its_cap_still_fits_its_graded_armhole():
    pat = sleeve_pattern()
    heights = {n: (lambda xy: np.asarray(xy)[:, 1]) for n in ("torso_front", "torso_back")}
    g = grade(pat, lambda n, xy: heights[n](xy), {"bust": (0.5, 0.9, 0.08)}, arm_change=0.02)
    arm = g.arms[0]
    assert sorted(arm["panels"]) == ["sleeve_back", "sleeve_front"]
    assert arm["girth_cm"] == pytest.approx(40.0, abs=0.01) and arm["scale"] == pytest.approx(1.05, abs=1e-6)
    assert arm["width_by"] == "upper arm" and arm["cap_scale"] != pytest.approx(1.0)
    # below the cap the sleeve is 0.2 * 1.05 wide, and its cap has the armhole's graded length
    assert np.ptp(g.pattern.panels["sleeve_front"].vertices[:2, 0]) == pytest.approx(0.21, abs=1e-9)
    for st in pat.stitches:
        assert abs(g.pattern.edge_length(st.a) - g.pattern.edge_length(st.b)) < 5e-4
    assert g.pattern.edge_length(EdgeRef("torso_front", 2)) > pat.edge_length(EdgeRef("torso_front", 2))


@pytest.fixture(scope="module")
def shirt():
    from vfit_engine.pattern.load import load

    return load(PATTERNS / "garmentcode_shirt_mean.json")[0]


@needs_shared
@pytest.mark.parametrize("change", [-0.08, 0.08])
def test_the_garmentcode_shirt_graded_a_size_down_and_up_validates_and_keeps_its_seams(shirt, change):
    from vfit_engine.pattern.placement import garmentcode_landmarks

    pat = shirt
    _, at = garmentcode_landmarks(pat.body)
    levels = {k: (at[k][0], at[k][1], change) for k in ("bust", "waist", "hips")}
    g = grade(pat, lambda n, xy: pat.panels[n].to_3d(xy)[:, 1], levels, change / 4,
              x_of=lambda n, xy: pat.panels[n].to_3d(xy)[:, 0])  # (grade validates it, or raises)
    assert set(g.levels) == {"bust", "waist"}  # the shirt ends above the hips
    assert g.levels["bust"]["scale"] == pytest.approx(1 + change / (g.levels["bust"]["garment_cm"] / 100), rel=1e-5)
    assert len(g.arms) == 2 and all(a["width_by"] == "upper arm" for a in g.arms)
    # a stitch's two lengths may differ by what they did before, grown with the panels, plus 2 mm
    grow = max([r["scale"] for r in g.levels.values()] + [a["scale"] for a in g.arms])
    for st, drift in zip(pat.stitches, stitch_drift(pat, g.pattern)):
        before = abs(pat.edge_length(st.a) - pat.edge_length(st.b))
        assert drift <= before * max(grow - 1, 0) + 0.002, st
    # the same change at every level of the boxy shirt (as wide at its hem as at its bust): its four torso
    # panels, halves of front and back, are wider by the change together
    torso = [n for n in pat.panels if "torso" in n]
    before = sum(np.ptp(pat.panels[n].vertices[:, 0]) for n in torso)
    after = sum(np.ptp(g.pattern.panels[n].vertices[:, 0]) for n in torso)
    assert after - before == pytest.approx(change, abs=0.005)


def test_a_pattern_with_no_body_and_no_gender_is_refused(body_model):
    with pytest.raises(InputError, match="names no body.*--gender"):
        made_for(tube(), body_model, None)
    made = made_for(tube(), body_model, "male")
    assert made.text.startswith("made for: unknown") and "default male body" in made.text
    assert 0.8 < made.girths["bust"] < 1.2 and made.heights["bust"] > made.heights["waist"] > made.heights["hips"]
