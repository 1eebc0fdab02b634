"""DXF-AAMA: the polyline curve, write -> read round trips, files as other CAD systems write them, the sidecar,
and every refusal of a bad file."""
import json
import math

import ezdxf
import numpy as np
import pytest

from vfit_engine.errors import InputError
from vfit_engine.pattern import curves, dxf_aama, model, seams


# ---------------------------------------------------------------------------------------------- the polyline
def test_polyline_kind_length_and_arc_length_sampling():
    ends, controls = ((0.0, 0.0), (3.0, 4.0)), ((3.0, 0.0),)  # an L: 3 along x, then 4 up
    assert "polyline" in curves.KINDS
    assert curves.length("polyline", ends, controls) == pytest.approx(7.0)
    pts = curves.sample("polyline", ends, controls, np.array([0.0, 3 / 7, 0.5, 1.0]))
    np.testing.assert_allclose(pts, [[0, 0], [3, 0], [3, 0.5], [3, 4]], atol=1e-12)
    np.testing.assert_allclose(curves.chords("polyline", ends, controls), [[0, 0], [3, 0], [3, 4]])


def test_chords_of_an_arc_stay_within_their_tolerance():
    r, tol = 0.3, 1e-4
    mid = (r * math.cos(math.pi / 4), r * math.sin(math.pi / 4))
    pts = curves.chords("circle", ((r, 0.0), (0.0, r)), (mid,), tol)
    np.testing.assert_allclose(np.linalg.norm(pts, axis=1), r, atol=1e-12)  # on the circle
    halfway = np.linalg.norm(0.5 * (pts[:-1] + pts[1:]), axis=1)
    assert r - halfway.min() <= tol          # the sagitta r (1 - cos(theta / 2)) within the tolerance
    assert r - halfway.min() > tol / 5       # and not ten times finer than asked


# ---------------------------------------------------------------------------------------------- round trips
def _rect(name, w, h, **kw):
    v = np.array([[0, 0], [w, 0], [w, h], [0, h]], float)
    return model.Panel(name, v, [model.Edge(i, (i + 1) % 4) for i in range(4)], **kw)


def _curvy():
    """A panel with a line, a circular arc (a half disc of radius 0.1 on top) and a cubic side."""
    v = np.array([[0.0, 0.0], [0.2, 0.0], [0.2, 0.3], [0.0, 0.3]])
    edges = [model.Edge(0, 1), model.Edge(1, 2, "cubic", ((0.3, 0.1), (0.25, 0.2))),
             model.Edge(2, 3, "circle", ((0.1, 0.4),)), model.Edge(3, 0)]
    return model.Panel("curvy", v, edges, grain=np.array([1.0, 1.0]) / math.sqrt(2))


def _same_outline(a, b, tol=1e-3):
    assert len(a.edges) == len(b.edges)
    s = np.linspace(0.0, 1.0, 101)
    for i in range(len(a.edges)):
        assert np.linalg.norm(a.edge_points(i, s) - b.edge_points(i, s), axis=1).max() < tol, i
        assert b.edge_length(i) == pytest.approx(a.edge_length(i), abs=1e-4)


def _stitches(p):
    return [(s.a, s.b, s.opposed, s.right_wrong) for s in p.stitches]


def test_a_rectangle_round_trips_with_its_grain_notches_lines_and_label(tmp_path):
    panel = _rect("front", 0.5, 0.7, label="body", grain=np.array([1.0, 0.0]),
                  notches=np.array([[0.5, 0.35]]), internal_lines=[np.array([[0.1, 0.1], [0.1, 0.5]])])
    p = model.Pattern({"front": panel}, [], source="shirt.json")
    dxf_aama.write(p, tmp_path / "p.dxf")
    doc = ezdxf.readfile(tmp_path / "p.dxf")
    assert doc.header["$INSUNITS"] == 4
    block = doc.blocks.get(doc.modelspace().query("INSERT")[0].dxf.name)
    layers = sorted({e.dxf.layer for e in block})
    assert layers == ["1", "2", "4", "7", "8"]
    turns = [tuple(e.dxf.location)[:2] for e in block.query("POINT[layer=='2']")]
    np.testing.assert_allclose(turns, panel.vertices * 1000.0)  # in mm, edge k's start first
    q = dxf_aama.read(tmp_path / "p.dxf")
    (r,) = q.panels.values()
    assert r.name == "front" and r.label == "body" and q.frame is None and q.stitches == []
    assert [e.kind for e in r.edges] == ["line"] * 4
    _same_outline(panel, r)
    np.testing.assert_allclose(r.grain, [1.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(r.notches, [[0.5, 0.35]], atol=1e-9)
    np.testing.assert_allclose(r.internal_lines[0], [[0.1, 0.1], [0.1, 0.5]], atol=1e-9)
    assert q.units_in_meter == pytest.approx(1000.0) and not q.warnings


def test_an_arc_and_a_cubic_round_trip_within_a_tenth_of_a_millimetre(tmp_path):
    panel = _curvy()
    p = model.Pattern({"curvy": panel}, [])
    dxf_aama.write(p, tmp_path / "c.dxf")
    r = dxf_aama.read(tmp_path / "c.dxf").panels["curvy"]
    assert [e.kind for e in r.edges] == ["line", "polyline", "polyline", "line"]
    _same_outline(panel, r, tol=1.5e-4)
    # the half circle as its chords, shorter than the arc by far less than its 0.1 mm chord error
    assert math.pi * 0.1 - 1e-4 < r.edge_length(2) < math.pi * 0.1
    np.testing.assert_allclose(r.grain, panel.grain, atol=1e-12)


@pytest.mark.parametrize("opposed", [True, False, None])
def test_two_panels_and_their_stitches_round_trip(tmp_path, opposed):
    p = model.Pattern({"front": _rect("front", 0.5, 0.7), "back": _curvy()},
                      [model.Stitch(model.EdgeRef("front", 1), model.EdgeRef("back", 1), opposed),
                       model.Stitch(model.EdgeRef("back", 0), model.EdgeRef("front", 0), True, right_wrong=True),
                       model.Stitch(model.EdgeRef("front", 3), model.EdgeRef("back", 3), False)])
    p.panels["back"].name = "back"
    dxf_aama.write(p, tmp_path / "p.dxf", tmp_path / "p.seams.json")
    q = dxf_aama.read(tmp_path / "p.dxf", tmp_path / "p.seams.json")
    assert list(q.panels) == ["front", "back"]
    assert _stitches(q) == _stitches(p)
    for name in p.panels:
        _same_outline(p.panels[name], q.panels[name], tol=1.5e-4)


# ---------------------------------------------------------------------------------------------- other systems' files
def _doc(units=None, insunits=0):
    doc = ezdxf.new("R2000", setup=False)
    doc.header["$INSUNITS"] = insunits
    for layer in ("1", "2", "4", "7", "14"):
        doc.layers.add(layer)
    if units:
        doc.modelspace().add_text(f"Units: {units}", dxfattribs={"layer": "1"})
    return doc


def test_pieces_in_the_model_space_in_inches_with_a_sew_line_and_no_turn_points(tmp_path):
    """Two pieces drawn straight in the model space (no blocks), inches, each a cut line (layer 1) with a sew
    line 0.5 in inside it (layer 14), notches on the cut line, no turn points; seams given by notch and xy."""
    doc = _doc("ENGLISH")
    msp = doc.modelspace()
    for k, name in enumerate(["left", "right"]):
        x0 = 20.0 * k
        msp.add_lwpolyline([(x0, 0), (x0 + 11, 0), (x0 + 11, 21), (x0, 21)], close=True, dxfattribs={"layer": "1"})
        msp.add_lwpolyline([(x0 + 0.5, 0.5), (x0 + 10.5, 0.5), (x0 + 10.5, 20.5), (x0 + 0.5, 20.5)], close=True,
                           dxfattribs={"layer": "14"})
        msp.add_text(f"Piece Name: {name}", dxfattribs={"layer": "1", "insert": (x0 + 2, 10)})
        msp.add_line((x0 + 5.5, 4), (x0 + 5.5, 16), dxfattribs={"layer": "7"})
        msp.add_point((x0 + 11, 10.5), dxfattribs={"layer": "4"})  # a notch on the cut line, mid side
    doc.saveas(tmp_path / "m.dxf")
    (tmp_path / "s.json").write_text(json.dumps({"seams": [
        {"a": {"piece": "left", "from": {"xy": [10.5, 0.5]}, "to": {"notch": 0}},
         "b": {"piece": "right", "from": {"xy": [20.5, 0.5]}, "to": {"xy": [20.5, 10.5]}, "backward": True}}]}))
    q = dxf_aama.read(tmp_path / "m.dxf", tmp_path / "s.json")
    inch = 0.0254
    left, right = q.panels["left"], q.panels["right"]
    np.testing.assert_allclose(np.ptp(left.outline(), axis=0), [10 * inch, 20 * inch], atol=1e-9)  # the sew line
    np.testing.assert_allclose(left.notches, [[10.5 * inch, 10.5 * inch]], atol=1e-9)  # onto the sew line
    (st,) = q.stitches
    assert st.opposed is True
    assert q.edge_length(st.a) == pytest.approx(10 * inch) == q.edge_length(st.b)
    a0, a1 = left.edge_ends(st.a.edge)
    b0, b1 = right.edge_ends(st.b.edge)
    np.testing.assert_allclose([a0, a1], np.array([[10.5, 0.5], [10.5, 10.5]]) * inch, atol=1e-9)
    np.testing.assert_allclose([b1, b0], np.array([[20.5, 0.5], [20.5, 10.5]]) * inch, atol=1e-9)  # b runs back
    # no turn points: the four corners end edges, the seams' ends split the sides
    assert len(left.edges) == 5 and len(right.edges) == 5
    assert any("no turn points" in w for w in q.warnings)


def test_a_block_of_loose_lines_in_millimetres_by_insunits(tmp_path):
    """A piece as a BLOCK whose boundary is four LINEs in no order and direction, units only in $INSUNITS (mm),
    an arc (bulge) on one side, turn points on layer 2 at the corners, and one more on an internal line."""
    doc = _doc(insunits=4)
    block = doc.blocks.new("P1")
    for a, b in [((0, 0), (100, 0)), ((0, 200), (0, 0)), ((100, 200), (0, 200))]:
        block.add_line(a, b, dxfattribs={"layer": "1"})
    block.add_lwpolyline([(100, 0, 1.0), (100, 200, 0)], format="xyb", dxfattribs={"layer": "1"})  # half circle
    for xy in [(0, 0), (100, 0), (100, 200), (0, 200), (50, 50)]:
        block.add_point(xy, dxfattribs={"layer": "2"})
    doc.modelspace().add_blockref("P1", (500, 500))
    doc.saveas(tmp_path / "b.dxf")
    q = dxf_aama.read(tmp_path / "b.dxf")
    (panel,) = q.panels.values()
    assert panel.name == "P1"
    assert sorted(round(panel.edge_length(i) * 1000, 1) for i in range(4)) == [100.0, 100.0, 200.0,
                                                                              round(100 * math.pi, 1)]
    np.testing.assert_allclose(panel.grain, [0.0, 1.0])
    assert any("no grain line" in w for w in q.warnings)


def test_a_seam_over_a_corner_is_one_edge(tmp_path):
    p = model.Pattern({"a": _rect("a", 0.3, 0.4), "b": _rect("b", 0.7, 0.1)}, [])
    dxf_aama.write(p, tmp_path / "p.dxf")
    (tmp_path / "s.json").write_text(json.dumps({"seams": [
        {"a": {"piece": "a", "from": {"turn": 0}, "to": {"turn": 2}},
         "b": {"piece": "b", "from": {"turn": 0}, "to": {"turn": 1}}}]}))
    q = dxf_aama.read(tmp_path / "p.dxf", tmp_path / "s.json")
    (st,) = q.stitches
    assert len(q.panels["a"].edges) == 3  # turn point 1 is inside the seam: not an edge's end
    assert q.edge_length(st.a) == pytest.approx(0.7) == q.edge_length(st.b)
    assert q.panels["a"].edges[st.a.edge].kind == "polyline" and st.opposed is False


# ---------------------------------------------------------------------------------------------- refusals
def _write(tmp_path, doc):
    doc.saveas(tmp_path / "bad.dxf")
    return tmp_path / "bad.dxf"


def test_bad_dxf_files_are_refused_naming_file_and_piece(tmp_path):
    doc = _doc("METRIC")
    doc.modelspace().add_text("just a title", dxfattribs={"layer": "1"})
    with pytest.raises(InputError, match=r"bad\.dxf: no pattern pieces"):
        dxf_aama.read(_write(tmp_path, doc))

    doc = _doc("METRIC")
    block = doc.blocks.new("SLEEVE")
    block.add_lwpolyline([(0, 0), (100, 0), (100, 100)], dxfattribs={"layer": "1"})  # not closed
    block.add_text("Piece Name: sleeve", dxfattribs={"layer": "1"})
    doc.modelspace().add_blockref("SLEEVE", (0, 0))
    with pytest.raises(InputError, match=r"bad\.dxf: block 'SLEEVE' \(piece 'sleeve'\): the outline on layer 1 is "
                                         r"open \(its ends are 141\.4 mm apart"):
        dxf_aama.read(_write(tmp_path, doc))

    doc = _doc("FURLONGS")
    doc.modelspace().add_lwpolyline([(0, 0), (1, 0), (1, 1)], close=True, dxfattribs={"layer": "1"})
    with pytest.raises(InputError, match=r"unknown units 'Units: FURLONGS'"):
        dxf_aama.read(_write(tmp_path, doc))

    doc = _doc(insunits=0)
    doc.modelspace().add_lwpolyline([(0, 0), (1, 0), (1, 1)], close=True, dxfattribs={"layer": "1"})
    with pytest.raises(InputError, match=r"no units.*\$INSUNITS is 0"):
        dxf_aama.read(_write(tmp_path, doc))

    (tmp_path / "junk.dxf").write_text("this is not a drawing\n")
    with pytest.raises(InputError, match=r"junk\.dxf: not a readable DXF"):
        dxf_aama.read(tmp_path / "junk.dxf")
    with pytest.raises(InputError, match=r"cannot read .*missing\.dxf"):
        dxf_aama.read(tmp_path / "missing.dxf")


def test_a_panel_whose_edges_do_not_chain_is_refused_on_writing(tmp_path):
    panel = _rect("front", 0.5, 0.7)
    panel.edges[1], panel.edges[2] = panel.edges[2], panel.edges[1]
    with pytest.raises(InputError, match=r"panel 'front' edge 0 ends at vertex 1 but edge 1 starts at 2"):
        dxf_aama.write(model.Pattern({"front": panel}, [], source="x.json"), tmp_path / "x.dxf")


@pytest.mark.parametrize("seam, message", [
    ({"a": {"piece": "nope", "from": {"turn": 0}, "to": {"turn": 1}}, "b": {"piece": "b", "from": {"turn": 0},
                                                                           "to": {"turn": 1}}},
     r"seam 0 side a: piece 'nope' is not in the DXF \(its pieces: 'a', 'b'\)"),
    ({"a": {"piece": "a", "from": {"xy": [150.0, 3.0]}, "to": {"turn": 1}}, "b": {"piece": "b", "from": {"turn": 0},
                                                                                 "to": {"turn": 1}}},
     r"seam 0 side a \('a'\) \"from\": the point \[150\.0, 3\.0\] is 3\.0 mm off the piece's outline"),
    ({"a": {"piece": "a", "from": {"turn": 1}, "to": {"xy": [300.0, 0.2]}}, "b": {"piece": "b", "from": {"turn": 0},
                                                                                 "to": {"turn": 1}}},
     r"seam 0 side a \('a'\): \"from\" and \"to\" are the same point of the outline, an empty edge"),
    ({"a": {"piece": "a", "from": {"turn": 0}, "to": {"notch": 0}}, "b": {"piece": "b", "from": {"turn": 0},
                                                                         "to": {"turn": 1}}},
     r"seam 0 side a \('a'\) \"to\": no notch 0 on this piece \(it has 0"),
    ({"a": {"piece": "a", "from": {"corner": 0}, "to": {"turn": 1}}, "b": {"piece": "b", "from": {"turn": 0},
                                                                          "to": {"turn": 1}}},
     r"seam 0 side a \('a'\) \"from\": unknown point kind 'corner'"),
    ({"a": {"piece": "a", "from": {"turn": 0}, "to": {"turn": 1}}},
     r"seam 0: give its two sides as objects \"a\" and \"b\""),
])
def test_bad_seams_are_refused(tmp_path, seam, message):
    p = model.Pattern({"a": _rect("a", 0.3, 0.4), "b": _rect("b", 0.3, 0.4)}, [])
    dxf_aama.write(p, tmp_path / "p.dxf")
    (tmp_path / "s.json").write_text(json.dumps({"seams": [seam]}))
    with pytest.raises(InputError, match=r"s\.json: " + message):
        dxf_aama.read(tmp_path / "p.dxf", tmp_path / "s.json")


def test_overlapping_seams_and_bad_json_are_refused(tmp_path):
    p = model.Pattern({"a": _rect("a", 0.3, 0.4), "b": _rect("b", 0.3, 0.4)}, [])
    dxf_aama.write(p, tmp_path / "p.dxf")
    side_b = {"piece": "b", "from": {"turn": 0}, "to": {"turn": 1}}
    (tmp_path / "s.json").write_text(json.dumps({"seams": [
        {"a": {"piece": "a", "from": {"turn": 0}, "to": {"turn": 2}}, "b": side_b},
        {"a": {"piece": "a", "from": {"turn": 1}, "to": {"turn": 3}}, "b": side_b}]}))
    with pytest.raises(InputError, match=r"a seam on piece 'a' .* runs past another seam's end"):
        dxf_aama.read(tmp_path / "p.dxf", tmp_path / "s.json")
    (tmp_path / "s.json").write_text("{not json")
    with pytest.raises(InputError, match=r"s\.json: not a JSON seams file"):
        dxf_aama.read(tmp_path / "p.dxf", tmp_path / "s.json")
    (tmp_path / "s.json").write_text("[]")
    with pytest.raises(InputError, match=r"a JSON object with a list \"seams\""):
        dxf_aama.read(tmp_path / "p.dxf", tmp_path / "s.json")


def test_outline_projection_snaps_to_its_own_points():
    o = seams.Outline("sq", np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float), np.zeros(0), np.zeros(0))
    assert o.length == pytest.approx(4.0)
    assert o.project([1.0002, 0.5]) == pytest.approx((1.5, 0.0002))
    assert o.project([1.0, 0.9997])[0] == 2.0  # within MERGE_M of the corner: the corner itself
    np.testing.assert_allclose(o.point_at(3.5), [0.0, 0.5])


def test_edges_starting_elsewhere_than_vertex_0_round_trip_edge_for_edge(tmp_path):
    """Turn point k is edge k's start, whatever the vertices' order: the read edges are the written ones."""
    v = np.array([[0, 0], [0.4, 0], [0.4, 0.6], [0, 0.6]], float)
    front = model.Panel("front", v, [model.Edge(2, 3), model.Edge(3, 0), model.Edge(0, 1), model.Edge(1, 2)])
    p = model.Pattern({"front": front, "back": _rect("back", 0.4, 0.6)},
                      [model.Stitch(model.EdgeRef("front", 3), model.EdgeRef("back", 3), True)])
    dxf_aama.write(p, tmp_path / "p.dxf", tmp_path / "s.json")
    q = dxf_aama.read(tmp_path / "p.dxf", tmp_path / "s.json")
    _same_outline(front, q.panels["front"])
    assert _stitches(q) == _stitches(p)
    np.testing.assert_allclose(q.panels["front"].edge_ends(3), [[0.4, 0.0], [0.4, 0.6]], atol=1e-12)
