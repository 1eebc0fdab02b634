"""Tests of the plane-section and girth kernels and of vfit_engine.section.MeshSections."""
from collections import Counter

import numpy as np
import pytest
import trimesh

import naive_section as naive
from vfit_engine.errors import InputError
from vfit_engine.kernels import girth as kg
from vfit_engine.section import MeshSections


def _y_up(mesh):
    """trimesh builds cylinders along z; turn the axis to +y (keeps outward winding)."""
    mesh.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0]))
    return mesh


def _cylinder(radius, sections, height=0.6, x=0.0):
    mesh = _y_up(trimesh.creation.cylinder(radius=radius, height=height, sections=sections))
    mesh.apply_translation([x, 0.0, 0.0])
    return mesh


def _star_prism(n_tips=5, r_out=0.2, r_in=0.08, y0=-0.5, y1=0.5):
    """Extruded star polygon (a non-convex section) with outward winding."""
    m = 2 * n_tips
    ang = np.arange(m) * np.pi / n_tips
    rad = np.where(np.arange(m) % 2 == 0, r_out, r_in)
    ring = np.stack([rad * np.cos(ang), np.zeros(m), rad * np.sin(ang)], axis=1)
    verts = np.vstack([ring + [0, y0, 0], ring + [0, y1, 0], [[0, y0, 0], [0, y1, 0]]])
    faces = []
    for i in range(m):
        j = (i + 1) % m
        faces += [[i, j, m + j], [i, m + j, m + i], [2 * m, j, i], [2 * m + 1, m + i, m + j]]
    mesh = trimesh.Trimesh(verts, np.array(faces), process=False)
    trimesh.repair.fix_normals(mesh)
    return mesh


def _bumpy_sphere(seed, subdivisions=3):
    rng = np.random.default_rng(seed)
    mesh = trimesh.creation.icosphere(subdivisions=subdivisions, radius=0.3)
    scale = 1.0 + 0.15 * rng.uniform(-1.0, 1.0, len(mesh.vertices))
    return trimesh.Trimesh(mesh.vertices * scale[:, None], mesh.faces, process=False)


def _sections(mesh):
    return MeshSections(mesh.faces, len(mesh.vertices))


def _inscribed(n, r):
    return 2.0 * n * r * np.sin(np.pi / n)


# ----------------------------------------------------------------------------- analytic sections

@pytest.mark.parametrize("y", [-0.25, -0.1, 0.0, 0.137, 0.29])
def test_cylinder_section_is_inscribed_polygon(y):
    n, r = 48, 0.15
    mesh = _cylinder(r, n)
    ms = _sections(mesh)
    loops, closed = ms.loops(mesh.vertices, y, return_closed=True)
    assert len(loops) == 1 and closed == [True]
    # ring vertices on the circle, diagonal-edge points on the chords between them
    rad = np.hypot(loops[0][:, 0], loops[0][:, 1])
    assert rad.max() == pytest.approx(r, rel=1e-12) and rad.min() >= r * np.cos(np.pi / n) * (1 - 1e-12)
    assert ms.girth(mesh.vertices, y, "hull") == pytest.approx(_inscribed(n, r), rel=1e-12)
    assert ms.girth(mesh.vertices, y, "polyline") == pytest.approx(_inscribed(n, r), rel=1e-12)
    # the spline rounds the polygon back towards the circle; the points on the
    # diagonal edges lie inside it, so it wobbles within 0.05 % of 2 pi r
    spline = ms.girth(mesh.vertices, y, "spline")
    assert _inscribed(n, r) < spline < 2 * np.pi * r * (1 + 5e-4)


def test_plane_through_vertex_ring_and_outside():
    """A vertex on the plane counts as above: the top ring is still cut, the bottom is not."""
    n, r = 32, 0.1
    mesh = _cylinder(r, n, height=0.6)
    ms = _sections(mesh)
    loops = ms.loops(mesh.vertices, 0.3)
    assert len(loops) == 1
    assert ms.girth(mesh.vertices, 0.3, "hull") == pytest.approx(_inscribed(n, r), rel=1e-12)
    # coincident points (two cut edges end at each ring vertex) must not break the spline
    assert ms.girth(mesh.vertices, 0.3, "spline") == pytest.approx(2 * np.pi * r, rel=2e-4)
    assert ms.loops(mesh.vertices, -0.3) == []
    assert np.isnan(ms.girth(mesh.vertices, -0.3))
    assert np.isnan(ms.girth(mesh.vertices, 1.0))


def test_box_section():
    a, b = 0.3, 0.2
    mesh = trimesh.creation.box(extents=(a, 1.0, b))
    ms = _sections(mesh)
    for y in (-0.3, 0.0, 0.41):
        assert ms.girth(mesh.vertices, y, "hull") == pytest.approx(2 * (a + b), rel=1e-12)
        assert ms.girth(mesh.vertices, y, "polyline") == pytest.approx(2 * (a + b), rel=1e-12)
        assert np.isfinite(ms.girth(mesh.vertices, y, "spline"))


def test_torso_loop_is_the_central_one():
    """Two 'arms' beside a 'torso': the girth is the torso's, whatever the order of the parts."""
    torso = _cylinder(0.15, 40)
    left = _cylinder(0.05, 24, x=-0.4)
    right = _cylinder(0.06, 24, x=0.4)
    for parts in ((left, torso, right), (right, left, torso), (torso, right, left)):
        mesh = trimesh.util.concatenate(parts)
        ms = _sections(mesh)
        assert len(ms.loops(mesh.vertices, 0.1)) == 3
        assert ms.girth(mesh.vertices, 0.1) == pytest.approx(_inscribed(40, 0.15), rel=1e-12)
        assert ms.girth(mesh.vertices, 0.1, x0=0.41) == pytest.approx(_inscribed(24, 0.06), rel=1e-12)
        # x0 inside no loop: nearest centroid (the right arm at 0.15 m, the torso at 0.25 m)
        assert ms.girth(mesh.vertices, 0.1, x0=0.25) == pytest.approx(_inscribed(24, 0.06), rel=1e-12)


def test_annulus_outer_loop_orientation():
    mesh = _y_up(trimesh.creation.annulus(r_min=0.1, r_max=0.2, height=0.5, sections=36))
    ms = _sections(mesh)
    loops = ms.loops(mesh.vertices, 0.05)
    areas = sorted(naive.signed_area(lp) for lp in loops)
    # outward winding: outer loop counter-clockwise in (x, z), the hole clockwise
    assert len(loops) == 2 and areas[0] < 0 < areas[1]
    assert areas[1] == pytest.approx(0.5 * 36 * 0.2 ** 2 * np.sin(2 * np.pi / 36), rel=1e-12)
    assert ms.girth(mesh.vertices, 0.05) == pytest.approx(_inscribed(36, 0.2), rel=1e-12)


def test_star_section_hull_bridges_hollows():
    n_tips, r_out, r_in = 5, 0.2, 0.08
    mesh = _star_prism(n_tips, r_out, r_in)
    ms = _sections(mesh)
    hull = ms.girth(mesh.vertices, 0.1, "hull")
    poly = ms.girth(mesh.vertices, 0.1, "polyline")
    side = np.sqrt(r_out ** 2 + r_in ** 2 - 2 * r_out * r_in * np.cos(np.pi / n_tips))
    assert hull == pytest.approx(_inscribed(n_tips, r_out), rel=1e-12)
    assert poly == pytest.approx(2 * n_tips * side, rel=1e-12)
    assert hull < poly


# ----------------------------------------------------------------------------- kernels vs references

def _check_loops_against_segments(loops, closed, segs):
    def key(p, q):
        return tuple(sorted([tuple(p), tuple(q)]))

    expected = Counter(key(s[0], s[1]) for s in segs)
    got = Counter()
    for lp, is_closed in zip(loops, closed):
        n = len(lp)
        for i in range(n if is_closed else n - 1):
            got[key(lp[i], lp[(i + 1) % n])] += 1
    assert got == expected


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_loops_match_naive_per_triangle_section(seed):
    mesh = _bumpy_sphere(seed)
    ms = _sections(mesh)
    rng = np.random.default_rng(100 + seed)
    for h in rng.uniform(-0.28, 0.28, 4):
        loops, closed = ms.loops(mesh.vertices, h, return_closed=True)
        assert all(closed)
        _check_loops_against_segments(loops, closed, naive.section_segments(mesh.vertices, mesh.faces, h))
        assert ms.girth(mesh.vertices, h) == pytest.approx(
            naive.hull_perimeter(loops[naive.torso_index(loops)]), rel=1e-12)


@pytest.mark.parametrize("seed", range(4))
def test_topology_matches_naive_tables(seed):
    """Edge tables against a dict of vertex pairs, on random soups (shared, boundary and non-manifold edges)
    and on a sphere."""
    from vfit_engine.kernels.section import build_topology

    rng = np.random.default_rng(seed)
    tris = rng.integers(3 * seed, 3 * seed + 30, size=(300, 3))
    tris = tris[(tris[:, 0] != tris[:, 1]) & (tris[:, 1] != tris[:, 2]) & (tris[:, 2] != tris[:, 0])]
    sphere = _bumpy_sphere(seed, subdivisions=2).faces
    for t in (tris, sphere):
        got, want = build_topology(t), naive.edge_tables(t)
        for g, w in zip(got, want):
            assert g.dtype == np.int64 and g.flags.c_contiguous
            np.testing.assert_array_equal(g, w)


def test_open_chains_at_mesh_boundary():
    mesh = _bumpy_sphere(7)
    centre = mesh.triangles_center
    keep = ~((centre[:, 2] > 0.15) & (np.abs(centre[:, 1]) < 0.12))
    mesh = trimesh.Trimesh(mesh.vertices, mesh.faces[keep], process=False)
    ms = _sections(mesh)
    loops, closed = ms.loops(mesh.vertices, 0.01, return_closed=True)
    assert closed == [False]
    _check_loops_against_segments(loops, closed, naive.section_segments(mesh.vertices, mesh.faces, 0.01))
    # an open chain keeps the walk orientation of the closed loops
    assert naive.signed_area(loops[0]) > 0
    loops, closed = ms.loops(mesh.vertices, -0.15, return_closed=True)
    assert closed == [True]


def test_hull_perimeter_matches_qhull():
    rng = np.random.default_rng(42)
    order = np.zeros(5000, dtype=np.int64)
    hull = np.zeros(10001, dtype=np.int64)
    cases = [rng.normal(size=(n, 2)) for n in (3, 4, 7, 50, 500, 3000)]
    cases.append(rng.integers(0, 6, size=(200, 2)).astype(np.float64))  # duplicates and collinear runs
    cases.append(np.vstack([rng.uniform(size=(40, 2)), [[0, 0], [1, 0], [1, 1], [0, 1]]]))
    for pts in cases:
        got = kg.hull_perimeter(np.ascontiguousarray(pts), order, hull)
        assert got == pytest.approx(naive.hull_perimeter(pts), rel=1e-12)


def test_hull_perimeter_degenerate():
    order = np.zeros(10, dtype=np.int64)
    hull = np.zeros(21, dtype=np.int64)
    assert kg.hull_perimeter(np.zeros((0, 2)), order, hull) == 0.0
    assert kg.hull_perimeter(np.ones((1, 2)), order, hull) == 0.0
    line = np.array([[0.0, 0.0], [3.0, 4.0], [1.5, 2.0], [0.6, 0.8]])
    assert kg.hull_perimeter(line, order, hull) == pytest.approx(10.0, rel=1e-15)


@pytest.mark.parametrize("n", [
    (0.0, 1.0, 0.0), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.0, 0.0, -1.0), (0.6, 0.0, 0.8),
    (3e-9, -1.0, 0.0), (0.0, -1.0, 2e-11), (1e-13, -1.0, 1e-13), (1e-7, 1.0, 0.0), (0.1, -0.995, 0.0),
])
def test_rotation_to_y_turns_the_normal_to_y(n):
    """A proper rotation (orthonormal, det 1) taking n to +Y, also for n within 1e-8 of -Y (where
    Rodrigues' 1 / (1 + cos) overflows: a ring's plane normal found pointing down)."""
    from vfit_engine.section import rotation_to_y

    n = np.asarray(n) / np.linalg.norm(n)
    r = rotation_to_y(n)
    assert np.all(np.isfinite(r))
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(r) == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(r @ n, [0.0, 1.0, 0.0], atol=1e-12)


def _random_loop(rng, n):
    ang = np.sort(rng.uniform(0, 2 * np.pi, n))
    rad = 0.1 + 0.05 * rng.uniform(size=n)
    return np.ascontiguousarray(np.stack([rad * np.cos(ang), rad * np.sin(ang)], axis=1))


def test_polyline_area_centroid_match_numpy():
    rng = np.random.default_rng(3)
    for n in (3, 10, 200):
        pts = _random_loop(rng, n)
        assert kg.polyline_length(pts, True) == pytest.approx(naive.polyline_length(pts), rel=1e-13)
        assert kg.polyline_length(pts, False) == pytest.approx(naive.polyline_length(pts, False), rel=1e-13)
        area, cx, xmin, xmax = kg.loop_area_centroid_xrange(pts)
        assert area == pytest.approx(naive.signed_area(pts), rel=1e-12)
        assert cx == pytest.approx(naive.centroid_x(pts), rel=1e-9, abs=1e-15)
        assert (xmin, xmax) == (pts[:, 0].min(), pts[:, 0].max())
        rev = np.ascontiguousarray(pts[::-1])
        assert kg.loop_area_centroid_xrange(rev)[0] == pytest.approx(-area, rel=1e-12)


def test_spline_matches_scipy_natural_cubic_spline():
    rng = np.random.default_rng(5)
    work = np.zeros((kg.SPLINE_WORK_ROWS, 1000))
    for n in (3, 4, 9, 60, 400):
        pts = _random_loop(rng, n)
        if n > 4:  # coincident neighbours are dropped by both
            pts = np.ascontiguousarray(np.insert(pts, [1, n // 2], pts[[1, n // 2]], axis=0))
        for samples in (1, 8):
            got = kg.spline_length(pts, samples, work)
            assert got == pytest.approx(naive.spline_length(pts, samples), rel=1e-11)
    circle = np.stack([np.cos(np.linspace(0, 2 * np.pi, 64, endpoint=False)),
                       np.sin(np.linspace(0, 2 * np.pi, 64, endpoint=False))], axis=1)
    assert kg.spline_length(np.ascontiguousarray(circle), 8, work) == pytest.approx(2 * np.pi, rel=1e-4)


def test_torso_selection_matches_reference():
    rng = np.random.default_rng(11)
    for trial in range(20):
        loops = []
        for _ in range(rng.integers(1, 5)):
            lp = _random_loop(rng, int(rng.integers(5, 30))) * rng.uniform(0.3, 2.0)
            loops.append(lp + [rng.uniform(-0.4, 0.4), 0.0])
        pts = np.ascontiguousarray(np.vstack(loops))
        starts = np.cumsum([0] + [len(lp) for lp in loops]).astype(np.int64)
        x0 = rng.uniform(-0.2, 0.2)
        assert kg.select_torso_loop(pts, starts, len(loops), x0) == naive.torso_index(loops, x0)
    assert kg.select_torso_loop(np.zeros((0, 2)), np.zeros(1, dtype=np.int64), 0, 0.0) == -1


def test_scan_equals_single_planes_and_is_deterministic():
    mesh = _bumpy_sphere(4)
    ms = _sections(mesh)
    for method in ("hull", "spline", "polyline"):
        ys, girths = ms.scan(mesh.vertices, -0.1, 0.1, step=0.004, method=method)
        assert len(ys) == 51 and ys[0] == -0.1 and ys[-1] == 0.1
        single = np.array([ms.girth(mesh.vertices, y, method) for y in ys])
        np.testing.assert_array_equal(girths, single)
        np.testing.assert_array_equal(girths, ms.scan(mesh.vertices, -0.1, 0.1, 0.004, method)[1])
    ys, _ = ms.scan(mesh.vertices, 0.0, 0.2)
    assert len(ys) == 201 and np.diff(ys).max() <= 0.001 + 1e-15
    ys, _ = ms.scan(mesh.vertices, 0.05, 0.05)
    assert list(ys) == [0.05]


def test_input_errors():
    mesh = _cylinder(0.1, 12)
    v, f = mesh.vertices, mesh.faces
    with pytest.raises(InputError):
        MeshSections(f[:, :2], len(v))
    with pytest.raises(InputError):
        MeshSections(f, len(v) - 1)
    with pytest.raises(InputError):
        MeshSections(f.astype(float), len(v))
    with pytest.raises(InputError, match="non-manifold"):
        third = next(i for i in range(len(v)) if i not in f[0])
        MeshSections(np.vstack([f, [[f[0, 0], f[0, 1], third]]]), len(v))
    ms = MeshSections(f, len(v))
    bad = v.copy()
    bad[3, 1] = np.nan
    for call in (lambda: ms.girth(bad, 0.0), lambda: ms.girth(v[:-1], 0.0), lambda: ms.girth(v, 0.0, "tape"),
                 lambda: ms.girth(v, np.nan), lambda: ms.scan(v, 0.2, 0.1), lambda: ms.scan(v, 0.0, 0.1, 0.0),
                 lambda: ms.loops(v, "high")):
        with pytest.raises(InputError):
            call()


# ----------------------------------------------------------------------------- the real body

@pytest.fixture(scope="module")
def body(body_model):
    verts = np.ascontiguousarray(body_model.default_verts("female")[:13380])
    return verts, np.asarray(body_model.body_tris)


def check_body(verts, tris):
    """Girths at hip, waist and bust level (fractions of stature above the soles) against
    trimesh's section + SciPy's hull; the spline against hull and polyline. Returns rows."""
    ms = MeshSections(tris, len(verts))
    mesh = trimesh.Trimesh(verts, tris, process=False)
    y_min, y_max = verts[:, 1].min(), verts[:, 1].max()
    rows = []
    for frac in (0.51, 0.60, 0.63, 0.72):
        y = y_min + frac * (y_max - y_min)
        path = mesh.section(plane_origin=[0.0, y, 0.0], plane_normal=[0.0, 1.0, 0.0])
        loops = [path.vertices[ent.points][:, [0, 2]] for ent in path.entities]
        ref = naive.hull_perimeter(loops[naive.torso_index(loops)])
        hull = ms.girth(verts, y, "hull")
        spline = ms.girth(verts, y, "spline")
        poly = ms.girth(verts, y, "polyline")
        assert abs(hull - ref) < 1e-4
        assert spline >= hull - 1e-3
        assert abs(spline - poly) < 0.03 * poly
        rows.append((y, hull, ref, spline, poly))
    return rows


def test_body_girths_match_trimesh_and_scipy(body):
    check_body(*body)


@pytest.mark.parametrize("method", [kg.METHOD_HULL, kg.METHOD_SPLINE])
def test_scan_with_plane_edge_lists_equals_scan_girths(body, method):
    """scan_girths_sorted (per-plane edge lists) against scan_girths (every band edge at every plane), on
    seeded jittered bodies: bit-identical girths (evenly and unevenly spaced planes, repeated ones); unsorted
    planes and too short lists take the fallback."""
    from vfit_engine.kernels import section as ks

    verts, tris = body
    ms = MeshSections(tris, len(verts))
    rng = np.random.default_rng(7)
    scratch = tuple(ms.scratch)
    for trial in range(3):
        v = np.ascontiguousarray(verts + rng.normal(0.0, 3e-4, verts.shape) * (trial > 0))
        lo = rng.uniform(0.8, 1.1)
        for ys in (np.linspace(lo, lo + 0.3, 301), np.linspace(lo, lo + 0.01, 11), np.array([lo]),
                   rng.uniform(lo, lo + 0.1, 20), np.sort(rng.uniform(lo - 0.2, lo + 0.1, 40)),
                   np.array([lo, lo, lo + 0.05]), np.array([5.0, 6.0])):
            topo = (v, ms.tris, ms.edges, ms.tri_edges, ms.edge_tris, ys, method, 8, 0.0)
            ref = np.empty(ys.size)
            ks.scan_girths(*topo, *scratch, ref)
            for cap in (4 * ms.edge_count, 10):
                out = np.empty(ys.size)
                ks.scan_girths_sorted(*topo, *scratch, np.empty(ys.size + 1, np.int64), np.zeros(cap, np.int64),
                                      out)
                np.testing.assert_array_equal(out, ref)



def test_apart_on_cylinders():
    """Three cylinders: apart; an arm moved onto the torso's x-range: not apart (the body: test_measure)."""
    torso, left, right = _cylinder(0.15, 40), _cylinder(0.05, 24, x=-0.4), _cylinder(0.05, 24, x=0.4)
    mesh = trimesh.util.concatenate((left, torso, right))
    assert _sections(mesh).apart(mesh.vertices, [0.1]).tolist() == [True]
    mesh = trimesh.util.concatenate((left, torso, _cylinder(0.05, 24, x=0.12)))
    assert _sections(mesh).apart(mesh.vertices, [0.1]).tolist() == [False]
