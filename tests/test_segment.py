"""Body segmentation: voxeliser, BFS and flood-fill kernels against references, the 17 parts on the
real body (coverage, connectivity, symmetry, skin-weight agreement), the six-part split, ``vfit segment``."""
import json
from collections import deque

import numpy as np
import pytest
from click.testing import CliRunner

from vfit_engine.body.segment import (PARTS, SIX_PARTS, bone_part, fill_compare, segment, six_part_split,
                                      voxelise, VoxelGrid)
from vfit_engine.kernels.flood import multi_source_bfs, nearest_solid


def _centres(grid):
    return grid.centres(np.arange(grid.solid.size))


# ---------------------------------------------------------------------------------------- voxeliser
def test_voxelise_box_matches_analytic_inside():
    import trimesh

    box = trimesh.creation.box(extents=(0.1, 0.06, 0.08))
    box.apply_translation((0.013, -0.2, 0.031))
    g = voxelise(box.vertices, box.faces, 0.005)
    c = _centres(g)
    lo, hi = box.bounds
    want = np.all((c > lo) & (c < hi), axis=1)
    assert g.odd_columns == 0
    assert np.array_equal(g.solid.astype(bool), want)


def test_voxelise_sphere_volume_and_reference():
    import trimesh

    s = trimesh.creation.icosphere(subdivisions=4, radius=0.05)
    g = voxelise(s.vertices, s.faces, 0.004)
    r = np.linalg.norm(_centres(g), axis=1)
    solid = g.solid.astype(bool)
    assert g.odd_columns == 0
    # the icosphere lies between radius 0.99 r (its faces' least distance, subdivision 4) and r
    assert solid[r < 0.99 * 0.05].all() and not solid[r > 0.05].any()
    assert abs(g.solid.sum() * 0.004 ** 3 / s.volume - 1) < 0.03


# ---------------------------------------------------------------------------------------- kernels
def _grid(mask):
    """Pad a boolean (nx, ny, nz) mask with one empty voxel all round; flat uint8 and its shape."""
    m = np.pad(mask, 1)
    return np.ascontiguousarray(m.ravel().astype(np.uint8)), m.shape


def _bfs_reference(solid, shape, seeds):
    """Distance from each seed separately by plain BFS (slow, obvious)."""
    nx, ny, nz = shape
    offs = (1, -1, nz, -nz, ny * nz, -ny * nz)
    out = []
    for s in seeds:
        d = np.full(solid.size, -1)
        d[s] = 0
        q = deque([s])
        while q:
            v = q.popleft()
            for o in offs:
                u = v + o
                if solid[u] and d[u] < 0:
                    d[u] = d[v] + 1
                    q.append(u)
        out.append(d)
    return np.array(out)


def test_multi_source_bfs_matches_reference():
    rng = np.random.default_rng(7)
    solid, shape = _grid(rng.random((10, 9, 8)) < 0.7)
    cand = np.flatnonzero(solid)
    seeds = rng.choice(cand, 5, replace=False).astype(np.int64)
    labels = np.arange(5, dtype=np.int64) * 10
    lab, dist = np.empty(solid.size, np.int64), np.empty(solid.size, np.int64)
    multi_source_bfs(solid, *shape, seeds, labels, np.zeros(5, np.int64), lab, dist)
    ref = _bfs_reference(solid, shape, seeds)
    reach = (ref >= 0).any(axis=0)
    best = np.where(ref >= 0, ref, 10 ** 9).min(axis=0)
    assert np.array_equal(dist >= 0, reach)
    assert np.array_equal(dist[reach], best[reach])
    # the label is that of a seed at the least distance
    own = ref[lab[reach] // 10, np.flatnonzero(reach)]
    assert np.array_equal(own, best[reach])


def test_multi_source_bfs_delay_moves_boundary():
    solid, shape = _grid(np.ones((1, 1, 21), bool))
    seeds = np.array([1 + 0, 1 + 20], dtype=np.int64) + (shape[1] + 1) * shape[2]  # ends of the line
    lab, dist = np.empty(solid.size, np.int64), np.empty(solid.size, np.int64)
    for delay, left in ((0, 11), (4, 13)):
        multi_source_bfs(solid, *shape, seeds, np.array([0, 1]), np.array([0, delay]), lab, dist)
        assert np.count_nonzero(lab == 0) == left  # ties go to the first seed


def test_nearest_solid_matches_brute_force():
    rng = np.random.default_rng(3)
    solid, shape = _grid(rng.random((8, 8, 8)) < 0.05)
    h = 0.01
    g = VoxelGrid(solid, np.zeros(3), h, shape, 0)
    pts = rng.random((200, 3)) * np.array(shape) * h
    got = np.empty(200, np.int64)
    nearest_solid(pts, 0.0, 0.0, 0.0, h, solid, *shape, 20, got)
    c = g.centres(np.flatnonzero(solid))
    d = np.linalg.norm(pts[:, None] - c[None], axis=2)
    assert np.allclose(np.linalg.norm(g.centres(got) - pts, axis=1), d.min(axis=1))


def _torus(n=40):
    x = (np.arange(n) + 0.5) / n * 2 - 1
    X, Y, Z = np.meshgrid(x, x, x, indexing="ij")
    return (np.sqrt(X ** 2 + Z ** 2) - 0.6) ** 2 + Y ** 2 < 0.25 ** 2


def _l_room(n=60):
    """A 2-D L-shaped room with a pillar and a wall with a door, as one layer."""
    room = np.zeros((n, n), bool)
    room[:, : n // 3] = True
    room[: n // 3, :] = True
    room[5:9, 5:9] = False
    room[n // 3 - 1, n // 3 + 2:n - 3] = False  # a wall across the upper arm with a 2-voxel door at the end
    room[n // 3 - 1, :2] = False
    return room[None]


@pytest.mark.parametrize("shape_fn", [_torus, _l_room])
def test_span_fill_same_set_fewer_pushes(shape_fn):
    from scipy import ndimage

    solid, shape = _grid(shape_fn())
    g = VoxelGrid(solid, np.zeros(3), 1.0, shape, 0)
    seed = int(np.flatnonzero(solid)[0])
    st = fill_compare(g, seed)
    comp, _ = ndimage.label(solid.reshape(shape))  # 6-connected (4 in a layer) reference
    want = comp.ravel() == comp.ravel()[seed]
    assert st["same_set"] and st["filled"] == want.sum()
    assert st["stack"]["pushes"] == st["filled"]
    assert st["span"]["pushes"] < st["stack"]["pushes"] / 3
    assert st["span"]["visits"] < st["stack"]["visits"]
    assert st["span"]["peak"] < st["stack"]["peak"]


# ---------------------------------------------------------------------------------------- real body
def test_bone_part_table():
    assert bone_part("spine03") == "abdomen" and bone_part("spine01") == "chest"
    assert bone_part("pelvis.L") == "pelvis" and bone_part("root") == "pelvis"
    assert bone_part("upperarm02.L") == "upperarm.L" and bone_part("finger3-2.R") == "hand.R"
    assert bone_part("toe1-1.L") == "foot.L" and bone_part("lowerleg01.R") == "shin.R"
    assert bone_part("oris03.L") == "head" and bone_part("neck02") == "neck"


@pytest.fixture(scope="module")
def female(body_model):
    return body_model.default_verts("female")


@pytest.fixture(scope="module")
def seg(body_model, female):
    return segment(body_model, female)


def _largest_component_share(model, labels, part):
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    q = model.body_quads
    e = np.concatenate([q[:, [0, 1]], q[:, [1, 2]], q[:, [2, 3]], q[:, [3, 0]]])
    e = e[(labels[e[:, 0]] == part) & (labels[e[:, 1]] == part)]
    n = labels.size
    _, comp = connected_components(coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n)), directed=False)
    return np.bincount(comp[labels == part]).max() / np.count_nonzero(labels == part)


def test_every_vertex_has_a_part_and_parts_are_connected(body_model, seg):
    assert seg.labels.shape == (13380,) and seg.labels.min() >= 0 and seg.labels.max() < len(PARTS)
    assert all(seg.counts[p] > 0 for p in PARTS) and sum(seg.counts.values()) == 13380
    assert seg.odd_columns == 0
    for i, p in enumerate(PARTS):
        assert _largest_component_share(body_model, seg.labels, i) >= 0.95, p  # "nearly": the neck is 97 %


def test_left_right_symmetry(seg):
    for p in PARTS:
        if p.endswith(".L"):
            a, b = seg.counts[p], seg.counts[p[:-1] + "R"]
            assert abs(a - b) <= 0.03 * max(a, b), p


def test_agreement_with_skin_weights(body_model, seg):
    # 97.2 % on this body (94.3 % with no per-part delays); the issue asks >= 95 %
    assert seg.agreement >= 0.95
    male = segment(body_model, body_model.default_verts("male"))  # not used in tuning: 96.3 %
    assert male.agreement >= 0.95


def test_body_only_vertices_give_nearly_the_same_parts(body_model, female, seg):
    s13 = segment(body_model, female[:13380])  # bones carried over from the default body
    assert np.mean(s13.labels == seg.labels) > 0.99


def test_span_fill_on_body(seg):
    st = seg.fill_stats
    assert st["same_set"] and st["filled"] == st["reached"]
    assert st["span"]["pushes"] < st["stack"]["pushes"] / 5
    assert st["span"]["visits"] < st["stack"]["visits"]
    assert st["span"]["peak"] < st["stack"]["peak"]


def test_six_part_split_hands_in_arms_feet_in_legs(body_model, female, seg):
    lab = six_part_split(body_model, female)
    assert lab.shape == (13380,) and set(np.unique(lab)) == set(range(6))
    for part, six in (("hand.L", "arm.L"), ("hand.R", "arm.R"), ("foot.L", "leg.L"), ("foot.R", "leg.R")):
        m = seg.skin_labels == PARTS.index(part)
        assert np.all(lab[m] == SIX_PARTS.index(six)), part
    # the head's skin weights reach below the neck cut at the back of the skull and the jaw
    assert np.mean(lab[seg.skin_labels == 0] == 0) > 0.9
    counts = np.bincount(lab)
    assert counts[2] == counts[3] and counts[4] == counts[5]


# ---------------------------------------------------------------------------------------- CLI
@pytest.fixture(scope="module")
def body_file(tmp_path_factory, body_model, female):
    from vfit_engine.body.bodyio import write_body

    p = tmp_path_factory.mktemp("seg") / "body.obj"
    write_body(p, body_model, female)
    return p


def test_cli_segment(tmp_path, body_file):
    from vfit_cli.segment import segment as cmd
    from vfit_engine.io.mesh import read_mesh

    out, js = tmp_path / "parts.ply", tmp_path / "parts.json"
    r = CliRunner().invoke(cmd, [str(body_file), "-o", str(out), "--json", str(js)])
    assert r.exit_code == 0, r.output
    mesh = read_mesh(out)
    assert mesh.n_verts == 13380 and mesh.colors is not None
    rep = json.loads(js.read_text())
    assert rep["agreement_pct"] >= 95 and sum(rep["counts"].values()) == 13380
    assert len({tuple(c) for c in mesh.colors.tolist()}) == len(PARTS)
    assert rep["voxel_mm"] == 5 and "total_s" in rep["timings_s"]


def test_cli_segment_bad_input(tmp_path):
    import trimesh

    from vfit_cli.segment import segment as cmd

    ball = tmp_path / "ball.obj"
    trimesh.creation.icosphere(subdivisions=2).export(ball)
    cases = [[str(tmp_path / "missing.obj"), "-o", str(tmp_path / "a.ply")],
             [str(ball), "-o", str(tmp_path / "a.ply")],
             [str(ball), "-o", str(tmp_path / "a.obj")],
             [str(ball), "--voxel", "0"]]
    for args in cases:
        r = CliRunner().invoke(cmd, args)
        assert r.exit_code == 2, (args, r.output)
