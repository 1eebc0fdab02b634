"""Placement of pattern panels on vfit's body: the frame mapping, the automatic arrangement, the keyword table."""
import dataclasses
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import cKDTree

from vfit_engine.body.segment import SIX_PARTS
from vfit_engine.errors import InputError
from vfit_engine.geometry import closest_point_barycentric
from vfit_engine.pattern.model import Edge, EdgeRef, Panel, Pattern, Stitch
from vfit_engine.pattern.panel_slots import Slot, resolve_slots, slot_from_text
from vfit_engine.pattern.placement import GARMENTCODE_MEAN_BODY, garmentcode_landmarks, place
from vfit_engine.pattern.placement_body import BodyParts

PATTERNS = Path(__file__).resolve().parents[2] / "shared" / "assets" / "patterns"
CLEARANCE = 0.01


@pytest.fixture(scope="module")
def female(body_model):
    return BodyParts.from_model(body_model, body_model.default_verts("female"))


@pytest.fixture(scope="module")
def male(body_model):
    return BodyParts.from_model(body_model, body_model.default_verts("male"))


def rect(name, w, h, x0=0.0, y0=0.0, **kw):
    v = np.array([[x0, y0], [x0 + w, y0], [x0 + w, y0 + h], [x0, y0 + h]])
    return Panel(name, v, [Edge(0, 1), Edge(1, 2), Edge(2, 3), Edge(3, 0)], **kw)


def pattern_of(*panels, stitches=(), frame=None, source="test.json", body=None):
    return Pattern({p.name: p for p in panels}, list(stitches), source=source, frame=frame, body=body or {})


def dense(panel, per_edge=40):
    return panel.outline(per_edge)


# ---------------------------------------------------------------------------------------- body
def test_signed_distance_matches_brute_force(female):
    rng = np.random.default_rng(3)
    idx = rng.choice(len(female.surface), 40, replace=False)
    pts = female.surface[idx] + female.normals[idx] * rng.uniform(-0.02, 0.03, (40, 1)) \
        + rng.normal(0.0, 0.003, (40, 3))
    d, _ = female.signed_distance(pts)
    t = female.tris
    v = female.surface
    for p, di in zip(pts, d):
        pp = np.repeat(p[None], len(t), axis=0)
        w = closest_point_barycentric(pp, v[t[:, 0]], v[t[:, 1]], v[t[:, 2]])
        q = np.einsum("ij,ijk->ik", w, v[t])
        assert abs(abs(di) - np.linalg.norm(pp - q, axis=1).min()) < 1e-9
    # the sign: inside the torso is negative, in front of the chest positive
    torso = female.part_verts("torso")
    inside = torso.mean(0)
    front = torso[np.argmax(torso[:, 2])] + np.array([0.0, 0.0, 0.05])  # 5 cm before the bust point
    assert female.signed_distance(inside[None])[0][0] < -0.03
    assert 0.035 < female.signed_distance(front[None])[0][0] <= 0.05 + 1e-12


def test_girth_and_waist_of_a_tube():
    """A tube of 64-gon sections, narrowest (r = 0.1 m) from y = 0.4 to 0.6: its tape girth is the 64-gon's
    perimeter 2 n r sin(pi / n), and the waist the middle of the narrow stretch."""
    n, ys = 64, np.linspace(0.0, 1.0, 101)
    r = 0.1 + 0.5 * np.maximum(0.0, np.abs(ys - 0.5) - 0.1)
    ang = 2 * np.pi * np.arange(n) / n
    verts = np.concatenate([np.column_stack([ri * np.sin(ang), np.full(n, y), ri * np.cos(ang)])
                            for y, ri in zip(ys, r)])
    j = np.arange(n)
    quads = np.concatenate([np.column_stack([k * n + j, k * n + (j + 1) % n, (k + 1) * n + (j + 1) % n,
                                             (k + 1) * n + j]) for k in range(len(ys) - 1)])
    tris = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    tube = BodyParts(verts, tris, np.full(len(verts), SIX_PARTS.index("torso")), {})
    for y in (0.45, 0.503, 0.3):
        ri = 0.1 + 0.5 * max(0.0, abs(y - 0.5) - 0.1)
        g, centre = tube.girth(y)
        if abs(y - 0.5) <= 0.1:  # between two rings of one radius the section is the 64-gon itself
            assert g == pytest.approx(2 * n * ri * np.sin(np.pi / n), rel=1e-12)
        else:  # rings of different radii: the section's hull lies between the two rings' 64-gons
            assert 2 * n * (ri - 0.005) * np.sin(np.pi / n) < g < 2 * n * (ri + 0.005) * np.sin(np.pi / n)
        np.testing.assert_allclose(centre, 0.0, atol=1e-12)
    assert tube.narrowest(0.2, 0.9, step=0.01, tol=1e-9) == pytest.approx(0.5, abs=1e-9)
    assert tube.narrowest(0.45, 0.9, step=0.01, tol=1e-9) == pytest.approx(0.525, abs=1e-9)


# ---------------------------------------------------------------------------------------- frame mapping
def test_frame_mapping_by_hand(female):
    """A panel turned a quarter about z and moved: its points land where the landmarks and girths say."""
    heights, girths = garmentcode_landmarks(GARMENTCODE_MEAN_BODY)
    waist, armpit = heights["waist"], heights["armpit"]
    tx, tz = 0.05, 0.12
    # Rz(90): panel (x, y) -> (-y, x); translation puts the panel origin at the pattern body's waist
    panel = rect("left_ftorso", armpit - waist, 0.2, y0=-0.1, translation=np.array([tx, waist, tz]),
                 rotation=np.array([0.0, 0.0, 90.0]))
    pl = place(pattern_of(panel, frame="garmentcode", body=dict(GARMENTCODE_MEAN_BODY)), female,
               clearance=CLEARANCE)
    assert pl.method == {"left_ftorso": "frame"}
    xy = np.array([[0.0, 0.0], [armpit - waist, 0.0], [0.5 * (armpit - waist), 0.0], [0.0, -0.1]])
    got = pl.raw("left_ftorso", xy)
    lv = female.levels
    # heights: the landmarks onto vfit's landmarks, halfway between them halfway
    assert got[0, 1] == pytest.approx(lv["waist"], abs=1e-12)
    assert got[1, 1] == pytest.approx(lv["armpit"], abs=1e-12)
    assert got[2, 1] == pytest.approx(0.5 * (lv["waist"] + lv["armpit"]), abs=1e-12)
    # widths at the waist: offsets from the axis scaled by vfit's waist girth over the pattern body's
    g_vfit, centre = female.girth(lv["waist"])
    s = g_vfit / girths["waist"][1]
    assert girths["waist"][1] == pytest.approx(GARMENTCODE_MEAN_BODY["waist"] / 100.0)
    np.testing.assert_allclose(got[0, [0, 2]], centre + s * np.array([tx, tz]), atol=1e-12)
    # panel (0, -0.1) -> pattern (tx + 0.1, waist, tz): 0.1 more to the body's left, scaled
    np.testing.assert_allclose(got[3] - got[0], [0.1 * s, 0.0, 0.0], atol=1e-12)
    assert 0.7 < s < 1.2


def test_heights_between_landmarks_on_two_bodies(female, male):
    heights, _ = garmentcode_landmarks({})
    names = ("floor", "crotch", "waist", "armpit", "shoulder", "top")
    ys = np.array([heights[k] for k in names])
    mid = 0.5 * (ys[1:] + ys[:-1])
    panel = rect("torso_front", 0.01, 0.01)  # no rotation or translation: panel xy is the frame's xy
    got = {}
    for name, body in (("female", female), ("male", male)):
        pl = place(pattern_of(panel, frame="garmentcode"), body)
        at = pl.raw("torso_front", np.column_stack([np.zeros(len(ys)), ys]))[:, 1]
        lv = np.array([body.levels[k] for k in names])
        np.testing.assert_allclose(at, lv, atol=1e-12)
        half = pl.raw("torso_front", np.column_stack([np.zeros(len(mid)), mid]))[:, 1]
        np.testing.assert_allclose(half, 0.5 * (lv[1:] + lv[:-1]), atol=1e-12)
        got[name] = at
    # the male body is taller: every landmark above the floor is higher above his soles
    assert np.all((got["male"] - got["male"][0])[1:] > (got["female"] - got["female"][0])[1:])


# ---------------------------------------------------------------------------------------- wrapping
def _garment_set():
    """Torso halves, sleeves (caps sewn to the torso), a four-panel skirt, trousers, collar, waistband, cuff."""
    ps = [rect("left_ftorso", 0.26, 0.6), rect("right_ftorso", 0.26, 0.6, x0=-0.26),
          rect("left_btorso", 0.25, 0.6), rect("right_btorso", 0.25, 0.6, x0=-0.25),
          # a sleeve drawn lying down, its cap (edge 1, at x = 0.45) sewn to the torso
          rect("left_sleeve_f", 0.45, 0.2), rect("left_sleeve_b", 0.45, 0.2),
          rect("rfsleeve", 0.45, 0.2), rect("rbsleeve", 0.45, 0.2),
          rect("skirt_front", 0.5, 0.55), rect("skirt_back", 0.5, 0.55),
          rect("skirt_left", 0.3, 0.55), rect("skirt_right", 0.3, 0.55),
          rect("pants_left_front", 0.25, 0.9), rect("pants_right_back", 0.27, 0.9),
          rect("collar", 0.4, 0.05), rect("waistband", 0.75, 0.04), rect("cuff_left", 0.25, 0.05)]
    stitches = [Stitch(EdgeRef(s, 1), EdgeRef("left_ftorso", 1)) for s in ("left_sleeve_f", "left_sleeve_b")]
    stitches += [Stitch(EdgeRef(s, 1), EdgeRef("right_ftorso", 3)) for s in ("rfsleeve", "rbsleeve")]
    return pattern_of(*ps, stitches=stitches, frame=None, source="pieces.dxf")


@pytest.fixture(scope="module")
def wrapped(female):
    pat = _garment_set()
    return pat, place(pat, female, clearance=CLEARANCE)


def test_wrapped_methods_and_slots(wrapped):
    pat, pl = wrapped
    assert pl.method["left_ftorso"] == "wrapped: torso"
    assert pl.method["left_sleeve_b"] == "wrapped: arm.L"
    assert pl.method["rfsleeve"] == "wrapped: arm.R"
    assert pl.method["skirt_left"] == "wrapped: hips"
    assert pl.method["pants_left_front"] == "wrapped: leg.L"
    assert pl.method["pants_right_back"] == "wrapped: leg.R"
    assert pl.method["collar"] == "wrapped: neck"
    assert pl.method["cuff_left"] == "wrapped: arm.L"
    assert pl.slots["right_btorso"] == Slot("torso", "back", "right")


def test_wrapped_panels_outside_the_body(wrapped, female):
    pat, pl = wrapped
    for name, panel in pat.panels.items():
        d, _ = female.signed_distance(pl.to_body(name, dense(panel)))
        assert d.min() > CLEARANCE / 2, (name, d.min())
    # the skirt's ring clears the body by construction, before any push; the torso's clears the torso and
    # meets only the arms hanging beside it
    for name in ("skirt_front", "skirt_left", "skirt_back"):
        d, _ = female.signed_distance(pl.raw(name, dense(pat.panels[name])))
        assert d.min() > CLEARANCE / 2, (name, d.min())
    tree = cKDTree(female.surface)
    arms = [SIX_PARTS.index(p) for p in ("arm.L", "arm.R")]
    for name in ("left_ftorso", "right_ftorso", "left_btorso", "right_btorso"):
        p = pl.raw(name, dense(pat.panels[name]))
        d, _ = female.signed_distance(p)
        close = d < CLEARANCE / 2
        assert np.isin(female.labels[tree.query(p[close])[1]], arms).all(), name


def test_wrapped_panels_on_their_side(wrapped, female):
    pat, pl = wrapped
    torso = female.part_verts("torso")
    zc = 0.5 * (torso[:, 2].min() + torso[:, 2].max())

    def centre(name):
        return pl.to_body(name, dense(pat.panels[name])).mean(0)

    assert centre("left_ftorso")[2] > zc and centre("right_ftorso")[2] > zc
    assert centre("left_btorso")[2] < zc and centre("skirt_back")[2] < zc
    assert centre("left_ftorso")[0] > 0 > centre("right_ftorso")[0]
    assert centre("skirt_left")[0] > 0.1 and centre("skirt_right")[0] < -0.1
    # sleeves round their own arm: nearest body vertices on that arm
    arm_l, arm_r = (female.part_verts(p).mean(0) for p in ("arm.L", "arm.R"))
    for name, arm in (("left_sleeve_f", arm_l), ("left_sleeve_b", arm_l), ("rfsleeve", arm_r), ("rbsleeve", arm_r)):
        c = centre(name)
        other = arm_r if arm is arm_l else arm_l
        assert np.linalg.norm(c - arm) < np.linalg.norm(c - other) - 0.3, name
    assert centre("left_sleeve_f")[2] > centre("left_sleeve_b")[2]
    # trousers round their leg, in front or behind it; a cuff round the left wrist; a collar round the neck
    leg_l, leg_r = (female.part_verts(p).mean(0) for p in ("leg.L", "leg.R"))
    assert centre("pants_left_front")[0] > 0 and centre("pants_left_front")[2] > leg_l[2]
    assert centre("pants_right_back")[0] < 0 and centre("pants_right_back")[2] < leg_r[2]
    tree = cKDTree(female.surface)
    cuff = centre("cuff_left")
    assert SIX_PARTS[female.labels[tree.query(cuff)[1]]] == "arm.L"
    assert cuff[1] < female.levels["armpit"] - 0.15 and cuff[0] > 0.3
    collar = centre("collar")
    assert abs(collar[0]) < 0.01 and female.levels["shoulder"] < collar[1] < female.levels["shoulder"] + 0.05
    # tops at their landmarks: the torso at the shoulder line, the skirt at the waist
    lv = female.levels
    assert pl.raw("left_ftorso", [[0.1, 0.6]])[0, 1] == pytest.approx(lv["shoulder"])
    assert pl.raw("skirt_front", [[0.1, 0.55]])[0, 1] == pytest.approx(lv["waist"])
    # the sleeve's cap (sewn to the torso) is its top, near the shoulder; its hem lower down the arm
    cap = pl.raw("left_sleeve_f", [[0.45, 0.1]])[0]
    hem = pl.raw("left_sleeve_f", [[0.0, 0.1]])[0]
    assert cap[1] > hem[1] + 0.2 and hem[0] > cap[0] + 0.2


def test_wrapping_is_isometric(wrapped):
    """Lengths along the panel are kept: every edge's length in 3D within 1 % of its flat length."""
    pat, pl = wrapped
    s = np.linspace(0.0, 1.0, 201)
    for name, panel in pat.panels.items():
        for i in range(len(panel.edges)):
            p3 = pl.raw(name, panel.edge_points(i, s))
            length = np.linalg.norm(np.diff(p3, axis=0), axis=1).sum()
            assert length == pytest.approx(panel.edge_length(i), rel=0.01), (name, i)
        # and across the panel, a line along +x (bent round the cylinder): its arc length kept
        box = panel.vertices
        y = 0.5 * (box[:, 1].min() + box[:, 1].max())
        line = np.column_stack([np.linspace(box[:, 0].min(), box[:, 0].max(), 201), np.full(201, y)])
        p3 = pl.raw(name, line)
        assert np.linalg.norm(np.diff(p3, axis=0), axis=1).sum() == pytest.approx(np.ptp(box[:, 0]), rel=0.01)


def test_ring_panels_do_not_overlap(wrapped):
    """A ring's radius leaves room for all its panels: the skirt's four panels cover distinct angles."""
    pat, pl = wrapped
    angles = {}
    for name in ("skirt_front", "skirt_left", "skirt_back", "skirt_right"):
        p = pl.raw(name, dense(pat.panels[name]))
        a = np.degrees(np.arctan2(p[:, 0], p[:, 2]))
        angles[name] = a
    f, lft = angles["skirt_front"], angles["skirt_left"]
    assert f.max() < lft.min() + 1e-6  # the front ends before the left side begins (angles towards +x)


# ---------------------------------------------------------------------------------------- keywords
@pytest.mark.parametrize("text, slot", [
    ("left_ftorso", Slot("torso", "front", "left")),
    ("right_btorso", Slot("torso", "back", "right")),
    ("left_sleeve_f", Slot("sleeve", "front", None, "L")),
    ("right_sleeve_b", Slot("sleeve", "back", None, "R")),
    ("lfsleeve", Slot("sleeve", "front", None, "L")),
    ("rbsleeve", Slot("sleeve", "back", None, "R")),
    ("skirt_back", Slot("skirt", "back")),
    ("skirt_front", Slot("skirt", "front")),
    ("front", None),
    ("SleeveLeftBack", Slot("sleeve", "back", None, "L")),
    ("waistband", Slot("waistband", "front")),
    ("Collar", Slot("collar", "front")),
    ("right_sleeve_cuff_b", Slot("cuff", "back", None, "R")),
    ("pant_f_l", Slot("leg", "front", None, "L")),
    ("wb_back", Slot("waistband", "back")),
])
def test_keyword_table(text, slot):
    assert slot_from_text(text) == slot


def test_sides_alone_take_the_kind_from_the_file_or_the_sleeves():
    tee = pattern_of(rect("front", 0.4, 0.6), rect("back", 0.4, 0.6), source="/x/gpg_tee.json")
    assert resolve_slots(tee) == {"front": Slot("torso", "front"), "back": Slot("torso", "back")}
    skirt = pattern_of(*(rect(n, 0.3, 0.5) for n in ("front", "right", "back", "left")),
                       source="gpg_skirt_4_panels.json")
    slots = resolve_slots(skirt)
    assert slots["left"] == Slot("skirt", "left") and slots["front"] == Slot("skirt", "front")
    sewn = pattern_of(rect("front", 0.4, 0.6), rect("lfsleeve", 0.2, 0.3), source="a.dxf",
                      stitches=[Stitch(EdgeRef("lfsleeve", 1), EdgeRef("front", 1))])
    assert resolve_slots(sewn)["front"] == Slot("torso", "front")
    # GarmentCode's "leg" label on a skirt panel loses to the panel's name
    lab = pattern_of(rect("skirt_front", 0.4, 0.6, label="leg"), rect("panel_a", 0.4, 0.6, label="body"))
    assert resolve_slots(lab) == {"skirt_front": Slot("skirt", "front"), "panel_a": Slot("torso", "front")}


def test_unknown_part_is_refused_with_the_fix(female):
    pat = pattern_of(rect("torso_front", 0.4, 0.6), rect("piece7", 0.3, 0.3), source="shop/pieces.dxf")
    with pytest.raises(InputError) as e:
        place(pat, female)
    msg = str(e.value)
    assert "shop/pieces.dxf" in msg and "'piece7'" in msg and "mapping" in msg and "\n" not in msg
    pl = place(pat, female, mapping={"piece7": "sleeve right front"})
    assert pl.method["piece7"] == "wrapped: arm.R"
    with pytest.raises(InputError, match="piece7.*names no part"):
        place(pat, female, mapping={"piece7": "elbow patch"})
    with pytest.raises(InputError, match="cannot be mapped"):
        place(pat, female, arrange="frame")


# ---------------------------------------------------------------------------------------- shared patterns
@pytest.mark.skipif(not PATTERNS.is_dir(), reason="../shared is absent")
@pytest.mark.parametrize("name, method", [
    ("garmentcode_shirt_mean.json", "frame"), ("garmentcode_dress_pencil.json", "frame"),
    ("gpg_tee.json", "wrapped"), ("gpg_skirt_4_panels.json", "wrapped"),
])
def test_shared_patterns_placed(female, name, method):
    from vfit_engine.pattern.garmentcode import read

    pat = read(PATTERNS / name)
    pl = place(pat, female, clearance=CLEARANCE)
    for pname, panel in pat.panels.items():
        assert pl.method[pname].startswith(method)
        d, _ = female.signed_distance(pl.to_body(pname, dense(panel)))
        assert d.min() > CLEARANCE / 2, (pname, d.min())
    # a stitch's direction told from the placed panels (for a file that does not say it) is the file's own rule
    # (its reader's Stitch.opposed) wherever both edges are long enough for their ends to tell (2 cm: the dress's
    # 11 mm waist edge is not), the wrapped panels turned the file's way up
    for st in pat.stitches:
        if min(pat.edge_length(st.a), pat.edge_length(st.b)) > 0.02:
            assert pl.opposed(pat, dataclasses.replace(st, opposed=None)) == st.opposed, st
    if name == "gpg_tee.json":
        assert pl.method["lfsleeve"] == "wrapped: arm.L" and pl.method["front"] == "wrapped: torso"
    if name == "gpg_skirt_4_panels.json":
        assert set(pl.method.values()) == {"wrapped: hips"}


@pytest.mark.parametrize("alike", [False, True])
def test_sleeve_halves_meet_whichever_way_they_are_drawn(female, alike):
    """Two sleeve halves sewn along both long edges: one turns over so that the seams meet beside the arm.

    Drawn as mirror images (the usual: each seen from outside), the front's bottom edge meets the back's top
    edge, running against it; drawn alike, bottom meets bottom running the same way (``opposed=False``).
    """
    # cut with the grain along the arm (x): with no cap sewn, the grain tells which way is up the arm
    f, b = (rect(n, 0.4, 0.2, grain=np.array([1.0, 0.0])) for n in ("left_sleeve_f", "left_sleeve_b"))
    # edges of a rect: 0 bottom, 1 right, 2 top, 3 left
    pairs = [(0, 0), (2, 2)] if alike else [(0, 2), (2, 0)]
    st = [Stitch(EdgeRef("left_sleeve_f", i), EdgeRef("left_sleeve_b", j), opposed=False if alike else None)
          for i, j in pairs]
    pat = pattern_of(f, b, stitches=st)
    pl = place(pat, female)
    turned = pl.maps["left_sleeve_f"].mirror != pl.maps["left_sleeve_b"].mirror
    assert turned == (not alike)
    ring = pl.maps["left_sleeve_f"].ring
    over = np.cross(ring.up, ring.front)  # across the arm, from its front-back plane towards its top
    for s in st:
        a, c = (pl.raw(r.panel, pat.panels[r.panel].edge_points(r.edge, [0.5]))[0] for r in (s.a, s.b))
        # the seam's two edges on the same side of the arm (both over it or both under it), not across it
        assert np.sign((a - ring.origin) @ over) == np.sign((c - ring.origin) @ over) != 0, s
        assert pl.opposed(pat, s) == (not alike)
