"""Panels meshed as cloth (pattern.mesh) and sewn into one mesh (pattern.weld): the lattice along the grain, areas
against their closed forms, boundary segments, orientation, stitched edges' counts, a tube, a chain of stitches, a
cube's corner, the refusals, and the four shared patterns."""

import math
from pathlib import Path

import numpy as np
import pytest

from vfit_engine.errors import InputError
from vfit_engine.pattern import garmentcode, mesh
from vfit_engine.pattern.model import Edge, EdgeRef, Panel, Pattern, Stitch

PATTERNS = Path(__file__).resolve().parents[2] / "shared" / "assets" / "patterns"
needs_shared = pytest.mark.skipif(not PATTERNS.is_dir(), reason="../shared/assets/patterns absent")

LOOP4 = [Edge(0, 1), Edge(1, 2), Edge(2, 3), Edge(3, 0)]


def rect(name, w, h, grain=(0.0, 1.0), translation=(0.0, 0.0, 0.0), rotation=(0.0, 0.0, 0.0), clockwise=False):
    """A w x h rectangle from the origin; edges 0 bottom, 1 right, 2 top, 3 left (counter-clockwise), or, when
    ``clockwise``, the same rectangle wound the other way: edges 0 left (up), 1 top, 2 right (down), 3 bottom."""
    v = np.array([[0, 0], [w, 0], [w, h], [0, h]], float)
    if clockwise:
        v = v[[0, 3, 2, 1]]
    return Panel(name, v, list(LOOP4), grain=np.array(grain, float), translation=np.array(translation, float),
                 rotation=np.array(rotation, float))


def signed_areas(uv, faces):
    p = uv[faces]
    return 0.5 * ((p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1])
                  - (p[:, 1, 1] - p[:, 0, 1]) * (p[:, 2, 0] - p[:, 0, 0]))


def edge_uses(faces):
    e = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    return np.unique(e, axis=0, return_counts=True)


def boundary_vertices(m):
    return np.unique(np.concatenate(list(m.edge_vertices.values())))


# ---------------------------------------------------------------------- one panel
@pytest.mark.parametrize("degrees", [0.0, 30.0])
def test_the_lattice_runs_along_the_grain(degrees):
    """Away from the outline every edge is a lattice side: one spacing long, at 0, 60 or 120 degrees to the warp,
    and all three directions occur (one family of edges along the warp)."""
    t = math.radians(degrees)
    grain = (math.sin(t), math.cos(t))
    spacing = 0.02
    m = mesh.mesh_pattern(Pattern({"p": rect("p", 0.5, 0.8, grain=grain)}, []), spacing)
    inner = np.ones(m.vertex_count, bool)
    edges, _ = edge_uses(m.faces)
    on_outline = boundary_vertices(m)
    inner[on_outline] = False
    # 2 spacings clear of the outline: out of reach of the band between the lattice and the boundary
    u, v = m.uv[:, 0], m.uv[:, 1]
    inner &= (u > 2 * spacing) & (u < 0.5 - 2 * spacing) & (v > 2 * spacing) & (v < 0.8 - 2 * spacing)
    deep = edges[inner[edges[:, 0]] & inner[edges[:, 1]]]
    assert len(deep) > 500
    d = m.uv[deep[:, 1]] - m.uv[deep[:, 0]]
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), spacing, rtol=1e-9)
    along = np.degrees(np.arctan2(d[:, 0] * grain[1] - d[:, 1] * grain[0], d @ grain)) % 180.0
    family = np.rint(along / 60.0) % 3
    np.testing.assert_allclose(along, 60.0 * np.rint(along / 60.0), atol=1e-7)
    assert set(family.tolist()) == {0.0, 1.0, 2.0}
    # the yarn UVs turn the warp onto +V: warp-parallel edges have no U component there
    y = m.yarn_uv()
    dy = y[deep[:, 1]] - y[deep[:, 0]]
    warp = family == 0
    np.testing.assert_allclose(dy[warp, 0], 0.0, atol=1e-12)
    np.testing.assert_allclose(np.abs(dy[warp, 1]), spacing, rtol=1e-9)
    assert np.all(signed_areas(y, m.faces) > 0)


def test_a_polygon_is_covered_exactly_and_its_outline_is_made_of_edges():
    """An L-shaped panel wound clockwise: the triangles' area is the outline's (1e-9), every boundary segment is an
    edge of exactly one face, every other edge of two, all faces counter-clockwise in the panel frame."""
    v = np.array([[0, 0], [0, 0.6], [0.2, 0.6], [0.2, 0.25], [0.45, 0.25], [0.45, 0]], float)  # clockwise
    edges = [Edge(k, (k + 1) % 6) for k in range(6)]
    m = mesh.mesh_pattern(Pattern({"L": Panel("L", v, edges)}, []), 0.03)
    area = signed_areas(m.uv, m.faces)
    assert np.all(area > 0)
    exact = 0.2 * 0.6 + 0.25 * 0.25
    assert abs(area.sum() - exact) <= 1e-9 * exact
    keys, uses = edge_uses(m.faces)
    use = dict(zip(map(tuple, keys.tolist()), uses.tolist()))
    segments = set()
    for k in range(6):
        ix = m.edge_vertices[EdgeRef("L", k)]
        assert len(ix) - 1 == math.ceil(np.linalg.norm(v[(k + 1) % 6] - v[k]) / 0.03 - 1e-9)
        np.testing.assert_allclose(m.uv[ix[[0, -1]]], v[[k, (k + 1) % 6]], atol=1e-15)
        segments |= {tuple(sorted(p)) for p in zip(ix[:-1].tolist(), ix[1:].tolist())}
    assert all(use[s] == 1 for s in segments)
    assert all(u == 2 for e, u in use.items() if e not in segments)
    angle, aspect = m.quality()
    assert angle > 20.0 and aspect < 4.0


def test_a_curved_panel_is_covered_to_its_chords():
    """A half disc (a line and a circle arc): the mesh's area is the disc's less the n circular segments its arc's
    chords cut off, r^2 / 2 (theta - sin theta) each, theta = pi / n."""
    r = 0.3
    v = np.array([[-r, 0.0], [r, 0.0]])
    panel = Panel("d", v, [Edge(0, 1), Edge(1, 0, "circle", (np.array([0.0, r]),))])
    m = mesh.mesh_pattern(Pattern({"d": panel}, []), 0.02)
    n = len(m.edge_vertices[EdgeRef("d", 1)]) - 1
    assert n == math.ceil(math.pi * r / 0.02)
    theta = math.pi / n
    expected = math.pi * r * r / 2 - n * r * r / 2 * (theta - math.sin(theta))
    area = signed_areas(m.uv, m.faces)
    assert np.all(area > 0)
    assert abs(area.sum() - expected) <= 1e-9 * expected
    assert math.pi * r * r / 2 - area.sum() > 0.5 * n * r * r / 2 * (theta - math.sin(theta))  # the chords cut


def test_a_slit_narrower_than_the_spacing_refines_its_lips():
    """A 4 mm slit cut 25 cm into a panel meshed at 50 mm: the lips' segments are not Delaunay edges at their own
    counts (5), so the lips are refined until every boundary segment is an edge; nothing is dropped and the
    triangles cover the panel less the slit exactly."""
    g = 0.004
    v = np.array([[0, 0], [0.4, 0], [0.4, 0.3], [0.2 + g / 2, 0.3], [0.2 + g / 2, 0.05], [0.2 - g / 2, 0.07],
                  [0.2 - g / 2, 0.3], [0, 0.3]])
    m = mesh.mesh_pattern(Pattern({"s": Panel("s", v, [Edge(k, (k + 1) % 8) for k in range(8)])}, []), 0.05)
    lips = [len(m.edge_vertices[EdgeRef("s", k)]) - 1 for k in (3, 5)]
    assert lips[0] == lips[1] > 5
    assert len(m.edge_vertices[EdgeRef("s", 0)]) - 1 == 8        # the other edges keep their counts
    keys, uses = edge_uses(m.faces)
    use = dict(zip(map(tuple, keys.tolist()), uses.tolist()))
    for ix in m.edge_vertices.values():
        assert all(use.get(tuple(sorted(e)), 0) == 1 for e in zip(ix[:-1].tolist(), ix[1:].tolist()))
    area = signed_areas(m.uv, m.faces)
    assert np.all(area > 0)
    assert abs(area.sum() - (0.4 * 0.3 - g * (0.25 + 0.23) / 2)) < 1e-12


# ---------------------------------------------------------------------- stitches
def test_stitched_edges_take_the_larger_count_through_chains():
    """a's right edge (0.50 m) to b's left (0.52 m), b's right (0.52 m) to c's left (0.61 m): each stitch's edges
    take the larger count at 20 mm (26, 31); an edge sewn to nothing keeps its own; the pairs meet at one height."""
    p = Pattern({"a": rect("a", 0.3, 0.50), "b": rect("b", 0.3, 0.52), "c": rect("c", 0.3, 0.61)},
                [Stitch(EdgeRef("a", 1), EdgeRef("b", 3)), Stitch(EdgeRef("b", 1), EdgeRef("c", 3))])
    m = mesh.mesh_pattern(p, 0.02)
    counts = {r: len(ix) - 1 for r, ix in m.edge_vertices.items()}
    assert counts[EdgeRef("a", 1)] == counts[EdgeRef("b", 3)] == 26
    assert counts[EdgeRef("b", 1)] == counts[EdgeRef("c", 3)] == 31
    assert counts[EdgeRef("a", 3)] == 25 and counts[EdgeRef("b", 0)] == 15
    assert len(m.seam_pairs) == 27 + 32
    # no placement, both counter-clockwise: opposed, so the pairs meet at the same height
    np.testing.assert_allclose(m.uv[m.seam_pairs[:27, 0], 1] / 0.50, m.uv[m.seam_pairs[:27, 1], 1] / 0.52,
                               atol=1e-12)
    np.testing.assert_allclose(m.uv[m.seam_pairs[27:, 0], 1] / 0.52, m.uv[m.seam_pairs[27:, 1], 1] / 0.61,
                               atol=1e-12)


def test_an_edge_in_two_stitches_carries_the_count_through_the_chain():
    """b's left edge sewn to a's right and to c's left (a three-layer seam): a (0.50 m) takes c's 31 segments through
    b, though a and c share no stitch, and its vertices weld three by three."""
    p = Pattern({"a": rect("a", 0.3, 0.50), "b": rect("b", 0.3, 0.52), "c": rect("c", 0.3, 0.61)},
                [Stitch(EdgeRef("a", 1), EdgeRef("b", 3)), Stitch(EdgeRef("b", 3), EdgeRef("c", 3), False)])
    m = mesh.mesh_pattern(p, 0.02)
    counts = {r: len(ix) - 1 for r, ix in m.edge_vertices.items()}
    assert counts[EdgeRef("a", 1)] == counts[EdgeRef("b", 3)] == counts[EdgeRef("c", 3)] == 31
    w = m.welded()
    assert w.vertex_count == m.vertex_count - 2 * 32
    assert np.all(np.bincount(w.welded_index[m.edge_vertices[EdgeRef("a", 1)]], minlength=w.vertex_count)[
        w.welded_index[m.edge_vertices[EdgeRef("a", 1)]]] == 1)
    assert np.all(np.bincount(w.welded_index)[w.welded_index[m.edge_vertices[EdgeRef("a", 1)]]] == 3)


def _tube(clockwise_b=False, placed=False, opposed=None):
    w1, w2, h = 0.3, 0.25, 0.5
    kw = dict(translation=(w1, 0.0, -0.1), rotation=(0.0, 180.0, 0.0)) if placed else {}
    a = rect("a", w1, h, translation=(0.0, 0.0, 0.1) if placed else (0.0, 0.0, 0.0))
    b = rect("b", w2, h, clockwise=clockwise_b, **kw)
    # b's left edge is 3 when counter-clockwise, 0 when clockwise; its right edge 1 or 2
    left, right = (0, 2) if clockwise_b else (3, 1)
    p = Pattern({"a": a, "b": b}, [Stitch(EdgeRef("a", 1), EdgeRef("b", left), opposed),
                                   Stitch(EdgeRef("b", right), EdgeRef("a", 3), opposed)])
    return p, w1 + w2


@pytest.mark.parametrize("clockwise_b, placed", [(False, False), (True, False), (False, True)])
def test_two_rectangles_sew_into_a_tube(clockwise_b, placed):
    """Sewn along both long sides: a manifold tube (V - E + F = 0, every edge used once or twice), two openings
    each as long as the two widths summed, one orientation; the stitches' directions come from the windings (no
    placement) or from the panels' 3D ends."""
    p, girth = _tube(clockwise_b, placed)
    m = mesh.mesh_pattern(p, 0.02)
    w = m.welded()
    n = len(m.edge_vertices[EdgeRef("a", 1)])
    assert w.vertex_count == m.vertex_count - 2 * n
    edges, uses = w.edge_use()
    assert uses.max() == 2
    assert w.vertex_count - len(edges) + len(w.faces) == 0
    loops = w.boundary_loops()
    assert len(loops) == 2
    for loop in loops:
        assert abs(w.flat_length(loop) - girth) < 1e-9
    assert w.consistent
    assert w.on_seam.sum() == 2 * n
    assert not w.flipped.any()  # cut face up, or placed facing out: +z of both frames is the outside
    # the rest lengths: every edge as long as in the flat pattern; the seams' segments h / (n - 1) in both panels
    rest_edges, rest = w.flat_edge_lengths()
    np.testing.assert_array_equal(rest_edges, edges)
    seam = w.on_seam[rest_edges].all(axis=1) & (np.abs(np.diff(w.average(m.uv[:, 1])[rest_edges], axis=1)[:, 0])
                                                 > 1e-9)
    np.testing.assert_allclose(rest[seam], 0.5 / (n - 1), rtol=1e-12)
    assert seam.sum() == 2 * (n - 1)
    assert rest.min() > 0.3 * 0.02 and rest.max() < 2 * 0.02
    # the seam's pairs at one height: the pairing ran the right way
    ya, yb = m.uv[m.seam_pairs[:, 0], 1], m.uv[m.seam_pairs[:, 1], 1]
    np.testing.assert_allclose(ya, yb, atol=1e-12)
    if placed:
        # outwards: every face's normal points away from the tube's axis (x = w1 / 2, z = 0)
        x = w.average(m.xyz)
        f = x[w.faces]
        normal = np.cross(f[:, 1] - f[:, 0], f[:, 2] - f[:, 0])
        out = f.mean(axis=1) - [0.15, 0.0, 0.0]
        assert np.all(np.einsum("ij,ij->i", normal[:, [0, 2]], out[:, [0, 2]]) > 0)


def test_a_stitch_says_its_direction():
    p, _ = _tube(opposed=False)
    m = mesh.mesh_pattern(p, 0.02)
    ya, yb = m.uv[m.seam_pairs[:, 0], 1], m.uv[m.seam_pairs[:, 1], 1]
    np.testing.assert_allclose(ya + yb, 0.5, atol=1e-12)          # same direction: heights mirrored
    p.stitches = [Stitch(s.a, s.b, k != 0) for k, s in enumerate(p.stitches)]
    m = mesh.mesh_pattern(p, 0.02)
    n = len(m.edge_vertices[EdgeRef("a", 1)])
    ya, yb = m.uv[m.seam_pairs[:, 0], 1], m.uv[m.seam_pairs[:, 1], 1]
    np.testing.assert_allclose(ya[:n] + yb[:n], 0.5, atol=1e-12)  # not opposed: not swapped
    np.testing.assert_allclose(ya[n:], yb[n:], atol=1e-12)        # otherwise opposed


def test_a_corner_in_two_seams_welds_once():
    """Three squares sewn round a cube's corner (front a, right side b, top c): the corner where a's top right,
    b's top left and c's bottom right meet is one vertex; the sewn surface is a manifold with one opening."""
    s = 0.3
    p = Pattern({k: rect(k, s, s) for k in "abc"},
                [Stitch(EdgeRef("a", 1), EdgeRef("b", 3)), Stitch(EdgeRef("a", 2), EdgeRef("c", 0)),
                 Stitch(EdgeRef("b", 2), EdgeRef("c", 1))])
    m = mesh.mesh_pattern(p, 0.02)
    n = len(m.edge_vertices[EdgeRef("a", 1)]) - 1
    w = m.welded()
    assert w.vertex_count == m.vertex_count - 3 * n - 2
    corners = [m.edge_vertices[EdgeRef("a", 1)][-1], m.edge_vertices[EdgeRef("b", 3)][0],
               m.edge_vertices[EdgeRef("c", 0)][-1]]
    assert len(set(w.welded_index[corners].tolist())) == 1
    assert np.sum(w.welded_index == w.welded_index[corners[0]]) == 3
    _, uses = w.edge_use()
    assert uses.max() == 2 and w.consistent
    (loop,) = w.boundary_loops()
    assert abs(w.flat_length(loop) - 6 * s) < 1e-9


def test_a_short_seam_round_a_corner_does_not_double_a_triangle():
    """Two panels sewn along two consecutive edges, one of them 5 mm long (a shoulder's step, as in GarmentCode's
    armholes): the corner's ears would land on the same three welded vertices; they are split first."""
    v = np.array([[0, 0], [0.3, 0], [0.3, 0.4], [0.295, 0.4], [0, 0.4]], float)
    edges = [Edge(k, (k + 1) % 5) for k in range(5)]
    p = Pattern({"a": Panel("a", v, edges), "b": Panel("b", v.copy(), list(edges))},
                [Stitch(EdgeRef("a", 1), EdgeRef("b", 1), False), Stitch(EdgeRef("a", 2), EdgeRef("b", 2), False)])
    m = mesh.mesh_pattern(p, 0.02)
    w = m.welded()
    _, uses = w.edge_use()
    assert uses.max() <= 2
    assert np.all(signed_areas(m.uv, m.faces) > 0)


# ---------------------------------------------------------------------- refusals
def test_sewing_that_collapses_a_triangle_is_refused():
    """A triangle panel of one face whose edges 0 and 1 are sewn the same way: all three corners weld together."""
    v = np.array([[0, 0], [0.01, 0], [0, 0.01]], float)
    p = Pattern({"tiny": Panel("tiny", v, [Edge(0, 1), Edge(1, 2), Edge(2, 0)])},
                [Stitch(EdgeRef("tiny", 0), EdgeRef("tiny", 1), False)], source="t.json")
    m = mesh.mesh_pattern(p, 0.05)
    assert len(m.faces) == 1
    with pytest.raises(InputError, match=r"^t\.json: panel 'tiny': the triangle .* collapses to a line .*edge 0"):
        m.welded()


@pytest.mark.parametrize("spacing", [0.0, -0.01, float("nan"), float("inf")])
def test_a_spacing_that_is_no_length_is_refused(spacing):
    with pytest.raises(InputError, match="spacing must be a positive length"):
        mesh.mesh_pattern(Pattern({"p": rect("p", 0.3, 0.3)}, []), spacing)


def test_a_spacing_too_fine_is_refused():
    with pytest.raises(InputError, match="use a larger spacing"):
        mesh.mesh_pattern(Pattern({"p": rect("p", 1.0, 1.0)}, []), 0.0005)


@pytest.mark.parametrize("ref, message", [
    (EdgeRef("nope", 0), "stitch 0 names panel 'nope'"),
    (EdgeRef("p", 4), "stitch 0 names edge 4 of panel 'p', which has edges 0 to 3"),
])
def test_a_stitch_naming_no_edge_is_refused(ref, message):
    p = Pattern({"p": rect("p", 0.3, 0.3)}, [Stitch(EdgeRef("p", 0), ref)], source="s.json")
    with pytest.raises(InputError, match="^s.json: " + message):
        mesh.mesh_pattern(p, 0.05)


def test_edges_out_of_order_are_refused():
    v = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    panel = Panel("p", v, [Edge(0, 1), Edge(2, 3), Edge(1, 2), Edge(3, 0)])
    with pytest.raises(InputError, match="panel 'p', edge 0 ends at vertex 1 but edge 1 starts at vertex 2"):
        mesh.mesh_pattern(Pattern({"p": panel}, []), 0.1)


@pytest.mark.parametrize("corners, message", [
    ([[0, 0], [0.4, 0.3], [0.4, 0], [0, 0.4]], r"edge 0: the outline crosses itself near \(0.229, 0.171\) m"),
    ([[0, 0], [0.4, 0.4], [0.4, 0], [0, 0.4]], r"its outline passes twice through \(0.2000, 0.2000\) m"),
])
def test_a_crossing_outline_is_refused(corners, message):
    """Two bow ties: one crossing between samples (the crossing named), one through a sample of both edges."""
    v = np.array(corners, float)
    panel = Panel("bow", v, [Edge(k, (k + 1) % 4) for k in range(4)])
    with pytest.raises(InputError, match="^b.json: panel 'bow'.*" + message):
        mesh.mesh_pattern(Pattern({"bow": panel}, [], source="b.json"), 0.05)


# ---------------------------------------------------------------------- the shared patterns
OPENINGS = {  # file: openings of the sewn garment
    "garmentcode_shirt_mean.json": 4,      # neck, two sleeves, hem
    "garmentcode_dress_pencil.json": 4,    # neck, two armholes, hem
    "gpg_tee.json": 4,                     # neck, two sleeves, hem
    "gpg_skirt_4_panels.json": 2,          # waist, hem
}


@needs_shared
@pytest.mark.parametrize("name", sorted(OPENINGS))
def test_the_shared_patterns_sew_into_manifolds(name):
    p = garmentcode.read(PATTERNS / name)
    m = mesh.mesh_pattern(p)
    for s in p.stitches:
        assert len(m.edge_vertices[s.a]) == len(m.edge_vertices[s.b])
    assert np.all(signed_areas(m.uv, m.faces) > 0)
    angle, aspect = m.quality()
    assert angle > 20.0 and aspect < 4.0
    w = m.welded()
    edges, uses = w.edge_use()
    assert uses.max() == 2 and w.consistent
    loops = w.boundary_loops()
    assert len(loops) == OPENINGS[name]
    assert sum(len(lp) for lp in loops) == np.sum(uses == 1)  # every boundary edge on a closed opening
    assert 1500 < w.vertex_count < 4000
    # outwards by the 3D placement is GarmentCode's own convention: a panel faces where its outline winds
    for k, panel in enumerate(p.panels.values()):
        o = panel.outline()
        counter = np.sum(o[:, 0] * np.roll(o[:, 1], -1) - np.roll(o[:, 0], -1) * o[:, 1]) > 0
        assert w.flipped[k] == (not counter), m.panel_names[k]
