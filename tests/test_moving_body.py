"""The moving body's collider (vfit_engine.collide.moving_body): exact at every time of a frame, against a still
collider built there; the swept binning against a brute-force reference; sides carried over many frames; the
solver's contacts following the body (SolverVerlet.body_moved)."""
import math

import numpy as np
import pytest


def _sphere(subdivisions=3, radius=0.1):
    import trimesh

    s = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    return np.asarray(s.vertices, dtype=np.float64), np.asarray(s.faces, dtype=np.int64)


def _moved(verts, angle, shift, wobble=0.0):
    """``verts`` turned by ``angle`` about Z, moved by ``shift`` and squashed a little (a non-rigid part)."""
    c, s = math.cos(angle), math.sin(angle)
    rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    out = verts @ rot.T + np.asarray(shift)
    out[:, 1] *= 1.0 + wobble
    return out


def _points_near(verts, tris, n, spread, seed):
    rng = np.random.default_rng(seed)
    t = tris[rng.integers(0, len(tris), n)]
    b = rng.dirichlet([1.0, 1.0, 1.0], n)
    return np.einsum("ij,ijk->ik", b, verts[t]) + rng.normal(0.0, spread, (n, 3))


@pytest.fixture(scope="module")
def moving():
    """A sphere moved 12 cm and turned 40 degrees in one interval (many cells), with its two poses."""
    from vfit_engine.collide.moving_body import MovingBodyCollider

    v0, tris = _sphere()
    v1 = _moved(v0, math.radians(40), (0.12, 0.03, -0.02), wobble=0.1)
    both = np.concatenate([v0, v1])
    col = MovingBodyCollider(v0, tris, box=(both.min(axis=0), both.max(axis=0)), cell=0.015)
    col.advance(v1)
    return col, v0, v1, tris


@pytest.mark.parametrize("s", [0.0, 0.37, 1.0])
def test_queries_at_any_time_equal_a_still_collider_there(moving, s):
    from vfit_engine.collide.body_mesh import MeshCollider

    col, v0, v1, tris = moving
    col.at(s)
    now = v0 + s * (v1 - v0)
    np.testing.assert_array_equal(col.verts, now)
    still = MeshCollider(now, tris)
    pts = _points_near(now, tris, 4000, 0.03, seed=int(100 * s))
    for max_out, max_in in ((0.012, np.inf), (0.0, np.inf), (0.05, 0.05)):
        d, q, _, t = col.query(pts, max_out, max_in)
        d_ref, q_ref, _, t_ref = still.query(pts, max_out, max_in)
        band = np.isfinite(d_ref) & (d_ref < max_out) & (d_ref > -max_in)
        assert band.sum() > 500
        assert np.all(np.isfinite(d[band]))  # the band is answered exactly
        np.testing.assert_allclose(d[band], d_ref[band], rtol=0, atol=1e-12)
        np.testing.assert_allclose(q[band], q_ref[band], rtol=0, atol=1e-12)
        both = np.isfinite(d) & np.isfinite(d_ref)  # beyond it, exact where both computed it
        np.testing.assert_allclose(d[both], d_ref[both], rtol=0, atol=1e-12)
        far = ~np.isfinite(d)  # proven beyond the band: on the right side of it
        assert np.all(np.where(d[far] > 0, d_ref[far] >= max_out, d_ref[far] <= -max_in))
    col.settle_bounds()  # exact centre distances at this time: the same answers, faster
    d2, _, _, _ = col.query(pts, 0.0, np.inf)
    d_ref, _, _, _ = still.query(pts, 0.0, np.inf)
    assert np.array_equal(d2 < 0, d_ref < 0)
    inside = np.isfinite(d_ref) & (d_ref < 0)
    np.testing.assert_allclose(d2[inside], d_ref[inside], rtol=0, atol=1e-12)


def test_floored_queries_are_exact_within_their_floor(moving):
    """A query told how deep the point can be at most (``floored``, as the cloth's contacts know from an earlier
    query) stops searching beyond both bands, even in cells that do not know their side, and still answers every
    point within them exactly and every other as outside: against a still collider at the same time."""
    from vfit_engine._jit import njit
    from vfit_engine.collide.body_mesh import MeshCollider
    from vfit_engine.kernels.collide_mesh import query_point

    @njit
    def floored(points, grid, max_out, max_in, out):
        for p in range(points.shape[0]):
            out[p] = query_point(points[p, 0], points[p, 1], points[p, 2], grid, True, max_out, max_in[p], True)[0]

    col, v0, v1, tris = moving
    col.at(0.5)
    now = v0 + 0.5 * (v1 - v0)
    pts = _points_near(now, tris, 4000, 0.04, seed=11)
    d_ref = MeshCollider(now, tris).query(pts, np.inf, np.inf)[0]
    max_out = 0.012
    max_in = np.maximum(-d_ref, 0.0) + 0.001  # what the point's bound allows
    d = np.empty(len(pts))
    floored(pts, col.grid, max_out, max_in, d)
    near = d_ref < max_out
    assert near.sum() > 1000 and (~near).sum() > 1000 and (d_ref < -0.01).sum() > 100
    np.testing.assert_allclose(d[near], d_ref[near], rtol=0, atol=1e-12)
    assert np.all((d[~near] == np.inf) | (np.abs(d[~near] - d_ref[~near]) < 1e-12))


def test_swept_binning_against_brute_force():
    """Every cell whose centre comes within reach of a moving triangle (sampled at 61 times) is listed for it,
    at a level no higher than the closest distance seen; nothing is listed twice."""
    from vfit_engine.kernels import collide_mesh_build as B
    from vfit_engine.kernels import collide_mesh_sweep as S

    rng = np.random.default_rng(3)
    v0 = rng.uniform(-0.03, 0.03, (9, 3))
    v1 = v0 + rng.normal(0.0, 0.04, (9, 3))
    tris = np.array([[0, 1, 2], [3, 4, 5], [6, 7, 8]], dtype=np.int64)
    h, reach, piece = 0.01, 0.012, 0.01
    origin, dims = np.full(3, -0.1), np.full(3, 20, dtype=np.int64)
    ncells = int(np.prod(dims))
    cap = 200000
    cell, tri, level = np.empty(cap, np.int32), np.empty(cap, np.int32), np.empty(cap, np.uint8)
    n = S.bin_swept(v0, v1, tris, origin, dims, h, reach, piece, np.empty(ncells, np.int32),
                    np.empty(ncells, np.int32), cell, tri, level, np.empty(3))
    pairs = set(zip(cell[:n].tolist(), tri[:n].tolist()))
    assert len(pairs) == n
    ijk = np.stack(np.unravel_index(np.arange(ncells), tuple(dims)), axis=1)
    centres = origin + (ijk + 0.5) * h
    step = (reach + 0.5 * piece) / B.LEVELS
    for t in range(3):
        closest = np.full(ncells, np.inf)
        for s in np.linspace(0.0, 1.0, 61):
            a, b, c = (v0[tris[t]] + s * (v1[tris[t]] - v0[tris[t]]))
            closest = np.minimum(closest, _point_triangle_distance(centres, a, b, c))
        for cc in np.flatnonzero(closest <= reach * (1 - 1e-9)):
            assert (cc, t) in pairs
        mine = cell[:n][tri[:n] == t]
        assert np.all(level[:n][tri[:n] == t] * step <= closest[mine] + 1e-12)


def _point_triangle_distance(p, a, b, c):
    """(n,) distances from points ``p`` to triangle abc, by projection and the three edges (NumPy)."""
    n = np.cross(b - a, c - a)
    n = n / np.linalg.norm(n)
    d_plane = (p - a) @ n
    foot = p - d_plane[:, None] * n
    inside = np.ones(len(p), bool)
    for u, w in ((a, b), (b, c), (c, a)):
        inside &= np.cross(w - u, foot - u) @ n >= 0
    best = np.where(inside, np.abs(d_plane), np.inf)
    for u, w in ((a, b), (b, c), (c, a)):
        e = w - u
        t = np.clip((p - u) @ e / (e @ e), 0.0, 1.0)
        best = np.minimum(best, np.linalg.norm(p - (u + t[:, None] * e), axis=1))
    return best


def test_sides_carried_through_many_frames():
    """A sphere travelling 30 cm in six frames: a point deep inside it (beyond any cell's list) is found inside,
    at its exact depth, at every frame; the space it left is outside again."""
    from vfit_engine.collide.moving_body import MovingBodyCollider

    v0, tris = _sphere(subdivisions=2)
    poses = [_moved(v0, 0.2 * k, (0.05 * k, 0.0, 0.0)) for k in range(7)]
    both = np.concatenate(poses)
    col = MovingBodyCollider(poses[0], tris, box=(both.min(axis=0), both.max(axis=0)), cell=0.01)
    for k in range(1, 7):
        col.advance(poses[k])
        col.at(1.0)
        centre = poses[k].mean(axis=0)
        d, _, _, _ = col.query(np.array([centre, poses[0].mean(axis=0)]), max_out=0.0, max_in=np.inf)
        radius = np.linalg.norm(poses[k] - centre, axis=1).min()
        assert d[0] < 0 and abs(d[0] + radius) < 2e-3  # inside, ~ the inscribed radius deep
        if np.linalg.norm(centre - poses[0].mean(axis=0)) > 0.11:
            assert d[1] > 0  # where the sphere was is outside once it has left
    assert col.intervals == 6


def test_a_cloth_on_a_rising_body_is_carried(body_model):
    """A cloth patch resting on a sphere that rises 4 cm in one 1/30 s frame (as fast as a walking shin) ends
    above it, nothing inside, carried by the pushes (SolverVerlet.body_moved at every substep)."""
    from vfit_engine.collide.moving_body import MovingBodyCollider
    from vfit_engine.io.meshdata import mesh_from_faces
    from vfit_engine.sim.materials import resolve_material
    from vfit_engine.sim.model import Model
    from vfit_engine.sim.solver_verlet import ContactSettings, SolverVerlet, VerletSettings

    v0, tris = _sphere(subdivisions=3, radius=0.08)
    g = np.linspace(-0.03, 0.03, 7)
    x, z = np.meshgrid(g, g)
    cloth = np.stack([x.ravel(), np.full(x.size, 0.0825), z.ravel()], axis=1)
    quads = np.array([[r * 7 + c, (r + 1) * 7 + c, (r + 1) * 7 + c + 1, r * 7 + c + 1]
                      for r in range(6) for c in range(6)])
    mesh = mesh_from_faces(cloth, quads)
    model = Model.from_polygons(mesh.face_verts, mesh.face_offsets, cloth, resolve_material("cotton"))
    rise = np.array([0.0, 0.04, 0.0])
    col = MovingBodyCollider(v0, tris, box=(v0.min(axis=0), v0.max(axis=0) + rise), cell=0.01)
    solver = SolverVerlet(model, VerletSettings(substeps=16), ContactSettings(), body=col)
    state = solver.init_state(1.0 / 480.0, pos=cloth)
    solver.max_push = 0.02
    col.advance(v0 + rise)
    for k in range(16):
        col.at((k + 1) / 16)
        solver.body_moved(col.moved)
        solver.step(state, 1.0 / 480.0)
    d, _, _, _ = col.query(state.pos, max_out=0.05, max_in=np.inf)
    assert np.all(d > 0.0)
    top = 24  # the patch's centre, on the sphere's top: carried up the whole 4 cm, at the skin's clearance
    assert 0.038 < state.pos[top, 1] - cloth[top, 1] < 0.046
