"""A sewn pattern's figures per seam and per panel (fit.pattern_fit, drape.sew.PatternLabels) on a hand-built
final position where they are known: two rectangles sewn at both sides, stretched 4 % every way, one seam opened
by a hinge of known angle."""
from types import SimpleNamespace

import numpy as np
import pytest

from vfit_engine.drape.sew import PatternLabels, pattern_garment
from vfit_engine.fit.pattern_fit import SEAM_OPEN_MM, block_lines, panel_rows, pattern_block, seam_rows, worst
from vfit_engine.pattern.mesh import mesh_pattern
from vfit_engine.pattern.model import Edge, EdgeRef, Panel, Pattern, Stitch
from vfit_engine.pattern.weld import sewn_to

W, H = 0.20, 0.30  # each rectangle, m
STRETCH = 0.04


def _tube():
    """Two W x H rectangles, front and back, edges 0 bottom, 1 right, 2 top, 3 left; sewn right to right (the
    front's edge labelled "side") and left to left, the edges running the same way."""
    corners = np.array([[0.0, 0.0], [W, 0.0], [W, H], [0.0, H]])
    edges = [Edge(0, 1), Edge(1, 2), Edge(2, 3), Edge(3, 0)]
    front = Panel("front", corners, [Edge(0, 1), Edge(1, 2, label="side"), Edge(2, 3), Edge(3, 0)])
    back = Panel("back", corners.copy(), list(edges))
    stitches = [Stitch(EdgeRef("front", 1), EdgeRef("back", 1), opposed=False),
                Stitch(EdgeRef("front", 3), EdgeRef("back", 3), opposed=False)]
    pattern = Pattern({"front": front, "back": back}, stitches, source="tube.json")
    cloth = mesh_pattern(pattern, 0.04)
    keep = cloth.seam_pairs[:, 0] != cloth.seam_pairs[:, 1]
    garment = pattern_garment(pattern, cloth)
    setup = SimpleNamespace(garment=garment, rest=garment.verts.copy(), seams=cloth.seam_pairs[keep],
                            pattern=PatternLabels.of(pattern, cloth, keep))
    return pattern, cloth, setup


def _placed(cloth, hinge):
    """The cloth stretched uniformly by STRETCH; the front in z = 0, the back turned by ``hinge`` (rad) about
    the left seam's line (x = 0): the left seam shut, the right one open by 2 (1 + STRETCH) W sin(hinge / 2)."""
    p = (1.0 + STRETCH) * cloth.uv
    pos = np.column_stack([p, np.zeros(len(p))])
    back = cloth.vertex_panel == 1
    pos[back] = np.column_stack([p[back, 0] * np.cos(hinge), p[back, 1], -p[back, 0] * np.sin(hinge)])
    return pos


@pytest.fixture(scope="module")
def tube():
    return _tube()


def test_every_seam_pair_knows_its_stitch(tube):
    pattern, cloth, setup = tube
    labels = setup.pattern
    assert labels.seam_names == ("front:side <-> back:1", "front:3 <-> back:3")
    for k, s in enumerate(pattern.stitches):
        rows = cloth.seam_pairs[cloth.seam_stitch == k]
        assert set(rows[:, 0]) == set(cloth.edge_vertices[s.a].tolist())
        assert set(rows[:, 1]) == set(cloth.edge_vertices[s.b].tolist())


def test_a_seam_opened_by_a_known_gap_reports_it_and_a_uniform_stretch_reads_4_percent(tube):
    _, cloth, setup = tube
    hinge = 0.1
    rows = {r["seam"]: r for r in seam_rows(setup, _placed(cloth, hinge))}
    right, left = rows["front:side <-> back:1"], rows["front:3 <-> back:3"]
    gap = 1000.0 * 2.0 * (1.0 + STRETCH) * W * np.sin(hinge / 2)  # 20.8 mm, every pair of the right seam
    assert right["gap_max_mm"] == pytest.approx(gap, abs=1e-3)
    assert right["gap_mean_mm"] == pytest.approx(gap, abs=1e-3)
    assert right["pulled_open"] and not left["pulled_open"]
    assert left["gap_max_mm"] == pytest.approx(0.0, abs=1e-6)
    for r in (left, right):  # the seam line is stretched as the cloth is
        assert r["stretch_p99_pct"] == pytest.approx(100 * STRETCH, abs=1e-6)
        assert r["stretch_max_pct"] == pytest.approx(100 * STRETCH, abs=1e-6)
        assert r["pairs"] == int(np.ceil(H / 0.04)) + 1
    assert [r["seam"] for r in seam_rows(setup, _placed(cloth, hinge))][0] == right["seam"]  # worst first
    # just under the bar: closed
    small = 2 * np.arcsin(0.9 * SEAM_OPEN_MM / 1000 / (2 * (1 + STRETCH) * W))
    assert not any(r["pulled_open"] for r in seam_rows(setup, _placed(cloth, small)))


def test_panels_read_their_uniform_stretch_contact_and_ease(tube):
    _, cloth, setup = tube
    pos = _placed(cloth, 0.1)
    # the front's lower half rests on the body, the back does not touch it
    contact = ((cloth.vertex_panel == 0) & (cloth.uv[:, 1] < H / 2)).astype(float)
    fit_rows = [dict(region="waist", ease_cm=4.0, panels=[dict(panel="front", loop_share_pct=60.0, loop_draped_cm=24.0,
                                                               loop_made_cm=23.0),
                                                          dict(panel="back", loop_share_pct=40.0, loop_draped_cm=16.0,
                                                               loop_made_cm=15.5)]),
                dict(region="hips", ease_cm=None, verdict="not covered")]
    rows = {r["panel"]: r for r in panel_rows(setup, pos, dict(contact=contact), fit_rows)}
    for r in rows.values():
        for key in ("strain_p50_pct", "strain_p99_pct", "strain_max_pct"):
            assert r[key] == pytest.approx(100 * STRETCH, abs=1e-6)
        assert r["area_m2"] == pytest.approx(W * H, rel=1e-6)
    assert rows["back"]["contact_pct"] == 0.0
    assert 40.0 < rows["front"]["contact_pct"] < 60.0
    assert rows["front"]["regions"] == [dict(region="waist", loop_share_pct=60.0, loop_draped_cm=24.0,
                                             loop_made_cm=23.0, ease_cm=2.4)]
    assert rows["back"]["regions"][0]["ease_cm"] == 1.6  # the region's ease shared by the line: 4.0 x 40 %


def test_the_block_its_worst_and_its_lines(tube):
    _, cloth, setup = tube
    pos = _placed(cloth, 0.1)
    block = pattern_block(setup, pos, dict(contact=np.zeros(len(pos))), [])
    assert block["seams_pulled_open"] == 1 and block["seam_open_bar_mm"] == SEAM_OPEN_MM
    w = worst(block)
    assert w["worst_seam"] == "front:side <-> back:1" and w["worst_seam_gap_mm"] > 20.0
    assert w["worst_panel_p99_pct"] == pytest.approx(100 * STRETCH, abs=1e-3)
    assert worst(None) == dict(worst_seam=None, worst_seam_gap_mm=None, worst_panel=None, worst_panel_p99_pct=None)
    lines = block_lines(block, shown=1)
    assert lines[0].startswith("seams (1 of 2 pulled open, gap over 2 mm), the 1 worst")
    gap = 1000.0 * 2.0 * (1.0 + STRETCH) * W * np.sin(0.05)
    assert f"front:side <-> back:1: gap max {gap:.2f} mm" in lines[1] and "PULLED OPEN" in lines[1]
    assert all(("mm" in ln or "%" in ln) for ln in lines)  # a unit in every line
    assert pattern_block(SimpleNamespace(pattern=None), pos, {}, []) is None  # a garment mesh has none
    # the panels round a region, by their share of its line; a sliver under 5 % counted, not named
    fit_rows = [dict(region="hips", ease_cm=10.0, panels=[
        dict(panel="front", loop_share_pct=97.0, loop_draped_cm=97.0, loop_made_cm=95.0),
        dict(panel="back", loop_share_pct=3.0, loop_draped_cm=3.0, loop_made_cm=3.0)])]
    block = pattern_block(setup, pos, dict(contact=np.zeros(len(pos))), fit_rows)
    assert block_lines(block, fit_rows)[-1] == "  hips: front +9.7 cm (97 %) and 1 more under 5 %"


def test_an_opening_is_shared_by_its_panels_as_cut(tube):
    """The tube's bottom: the front's bottom edge then the back's, a seam's sides one vertex (as the fit table's
    openings are): each panel half of it, its part as cut W, draped (1 + STRETCH) W."""
    _, cloth, setup = tube
    pos = _placed(cloth, 0.0)  # shut: the back lies on the front
    weld = sewn_to(cloth.vertex_count, setup.seams)
    front, back = cloth.edge_vertices[EdgeRef("front", 0)], cloth.edge_vertices[EdgeRef("back", 0)]
    loop = weld[np.concatenate([front, back[::-1][1:-1]])]
    before = loop.copy()
    shares = {p["panel"]: p for p in setup.pattern.opening_panels(loop, pos, setup.rest, weld)}
    assert np.array_equal(loop, before)  # the caller's loop is not changed
    for p in shares.values():
        assert p["loop_share_pct"] == pytest.approx(50.0, abs=1e-6)
        assert p["loop_made_cm"] == pytest.approx(100 * W, abs=1e-6)
        assert p["loop_draped_cm"] == pytest.approx(100 * W * (1 + STRETCH), abs=1e-6)


def test_loop_panels_orders_by_share():
    labels = PatternLabels(("a", "b"), (), np.zeros(0, np.int64), np.array([0, 0, 1]))
    rows = labels.loop_panels([0, 1, 2], np.array([0.1, 0.1, 0.3]), np.array([0.1, 0.1, 0.25]))
    assert [r["panel"] for r in rows] == ["b", "a"]
    assert rows[0]["loop_share_pct"] == 60.0 and rows[0]["loop_made_cm"] == 25.0 and rows[1]["loop_draped_cm"] == 20.0


def test_a_tubes_line_round_a_cylinder_is_shared_by_its_two_halves():
    """loop_steps + PatternLabels.loop_panels: a 64-sided tube (radius 10 cm) cut at mid-height, its vertices
    on x >= 0 one panel, the rest another: each half of the line (the inscribed polygon's perimeter
    64 * 2 r sin(pi / 64)), every step as made its draped length / 1.04 (the rest shape is the tube shrunk 4 %)."""
    from test_fit import tube as quad_tube

    from vfit_engine.fit.loops import loop_steps
    from vfit_engine.fit.table import _Plane
    from vfit_engine.io.meshdata import mesh_from_faces

    verts, faces = quad_tube(0.10, 64, 5, 0.4, y0=-0.2)
    tris = mesh_from_faces(verts, faces).triangles()
    plane = _Plane((0.0, 0.01, 0.0), (0.0, 1.0, 0.0))
    own = 0.08 * np.column_stack([np.cos(np.linspace(0, 2 * np.pi, 64, endpoint=False)),
                                  np.sin(np.linspace(0, 2 * np.pi, 64, endpoint=False))])
    draped, made, vertex = loop_steps(tris, verts / (1 + STRETCH), verts, plane, own)
    assert draped.sum() == pytest.approx(64 * 2 * 0.10 * np.sin(np.pi / 64), rel=1e-9)
    np.testing.assert_allclose(made, draped / (1 + STRETCH), rtol=1e-9)
    half = np.where(verts[:, 0] >= -1e-12, 0, 1)
    labels = PatternLabels(("right", "left"), (), np.zeros(0, np.int64), half)
    rows = labels.loop_panels(vertex, draped, made)
    assert {r["panel"] for r in rows} == {"right", "left"}
    for r in rows:  # 32 of the 64 steps each, give or take the step at each end of a half
        assert r["loop_share_pct"] == pytest.approx(50.0, abs=100 / 64 + 1e-6)
        assert r["loop_made_cm"] == pytest.approx(r["loop_draped_cm"] / (1 + STRETCH), abs=0.011)
