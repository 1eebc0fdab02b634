"""HullCollider: analytic distances and pushes, kernels against NumPy references, fit invariants."""
import math
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

sys.path.insert(0, str(Path(__file__).resolve().parent))
import naive_collide  # noqa: E402

from vfit_engine.collide.hulls import HullCollider, fit_hulls, hull_planes  # noqa: E402
from vfit_engine.errors import InputError  # noqa: E402

AXES = np.array([[1.0, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]])


def box(lo, hi):
    """Planes of the axis-aligned box [lo, hi]."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    return AXES.copy(), np.array([hi[0], -lo[0], hi[1], -lo[1], hi[2], -lo[2]])


def cube_and_sphere(skin=0.0, friction=0.0, restitution=0.0):
    n, b = box([-0.5] * 3, [0.5] * 3)
    return HullCollider(n, b, [0, 6], [[3.0, 0, 0]], [1.0], parts=["cube", "ball"], skin=skin,
                        friction=friction, restitution=restitution)


# -- analytic ------------------------------------------------------------------------------------

@pytest.mark.parametrize("p, d", [
    ((0, 0, 0), -0.5), ((0.2, 0, 0), -0.3), ((0.5, 0.1, 0), 0.0), ((1, 0, 0), 0.5),
    ((1, 1, 0), math.sqrt(0.5)), ((1, 1, 1), math.sqrt(0.75)), ((-0.5, -0.7, 0.2), 0.2),
    ((3, 0, 0), -1.0), ((5, 0, 0), 1.0), ((3, 0, 0.5), -0.5), ((1.75, 0, 0), 0.25)])
def test_signed_distance_table(p, d):
    c = cube_and_sphere()
    assert c.signed_distance(np.array([p], float))[0] == pytest.approx(d, abs=1e-12)


def test_polytope_bookkeeping():
    c = cube_and_sphere()
    assert c.count == 2 and c.hull_count == 1 and c.sphere_count == 1 and c.parts == ["cube", "ball"]
    assert c.tris.shape == (12, 3) and c.tri_verts.shape == (8, 3)
    a, b, t = (c.tri_verts[c.tris[:, k]] for k in range(3))
    area = 0.5 * np.linalg.norm(np.cross(b - a, t - a), axis=1)
    assert area.sum() == pytest.approx(6.0)
    # outward winding: each triangle's normal points away from the centre
    assert np.all(np.einsum("ij,ij->i", np.cross(b - a, t - a), (a + b + t) / 3) > 0)


def test_redundant_planes_dropped():
    n, b = box([-1] * 3, [1] * 3)
    n = np.vstack([n, [1 / math.sqrt(3)] * 3])
    b = np.r_[b, 10.0]  # far outside the cube: touches nothing
    c = HullCollider(n, b, [0, 7])
    assert c.normals.shape == (6, 3)


def test_push_out_through_least_penetration_face_with_friction_restitution():
    cf, cr = 0.25, 0.5
    c = cube_and_sphere(skin=0.01, friction=cf, restitution=cr)
    x = np.array([[0.4, 0.1, 0.0], [0.4, 0.1, 0.0], [0.0, 0.0, 0.0], [2.0, 2.0, 2.0], [3.0, 0.0, 0.2]])
    xp = x - np.array([[-0.2, 0.1, 0.0], [-0.2, 0.1, 0.0], [0, 0, 0], [0.1, 0, 0], [0, 0, 0]])
    x0, xp0 = x.copy(), xp.copy()
    inv_mass = np.array([1.0, 0.0, 1.0, 1.0, 1.0])
    c.project(x, xp, inv_mass)
    np.testing.assert_allclose(x[0], [0.51, 0.1, 0.0], atol=1e-15)
    # v = (-0.2, 0.1, 0), n = +x: v_n = -0.2 reflected by Cr, v_t kept by 1 - Cf
    np.testing.assert_allclose(x[0] - xp[0], [cr * 0.2, (1 - cf) * 0.1, 0.0], atol=1e-15)
    assert np.array_equal(x[1], x0[1]) and np.array_equal(xp[1], xp0[1])  # pinned
    assert abs(np.abs(x[2]).max() - 0.51) < 1e-15  # centre: some face, pushed 0.51
    assert np.array_equal(x[3], x0[3]) and np.array_equal(xp[3], xp0[3])  # outside: untouched
    np.testing.assert_allclose(x[4], [3.0, 0.0, 1.01], atol=1e-15)  # radial push to R + skin


def test_overlap_candidate_blocked_goes_the_shortest_way_out():
    # two overlapping boxes forming [-0.5, 1.3] x [-0.5, 0.5]^2: the least-penetration pushes of
    # both boxes end inside the other one; the nearest way out of the union is sideways (0.5)
    na, ba = box([-0.5] * 3, [0.5] * 3)
    nb, bb = box([0.3, -0.5, -0.5], [1.3, 0.5, 0.5])
    c = HullCollider(np.vstack([na, nb]), np.r_[ba, bb], [0, 6, 12], skin=0.0)
    x = np.array([[0.45, 0.0, 0.0]])
    xp = x.copy()
    c.project(x, xp, np.ones(1))
    assert np.linalg.norm(x[0] - [0.45, 0, 0]) == pytest.approx(0.5, abs=1e-12)
    assert c.signed_distance(x)[0] >= -1e-12


def test_bad_input():
    n, b = box([-1] * 3, [1] * 3)
    with pytest.raises(InputError):
        HullCollider(n[:5], b[:5], [0, 5])  # unbounded
    with pytest.raises(InputError):
        HullCollider(n, b - 5.0, [0, 6])  # empty
    with pytest.raises(InputError):
        HullCollider(n, b, [0, 5])
    with pytest.raises(InputError):
        HullCollider(n, b, [0, 6], [[0, 0, 0]], [-1.0])
    with pytest.raises(InputError):
        HullCollider(n, b, [0, 6], friction=2.0)
    v = np.random.default_rng(0).normal(size=(50, 3))
    with pytest.raises(InputError):
        fit_hulls(v, np.full(50, 3), ["a", "b"])
    with pytest.raises(InputError):
        fit_hulls(v, np.zeros(49, dtype=np.int64), ["a"])
    with pytest.raises(InputError):
        fit_hulls(v[:10], np.zeros(10, dtype=np.int64), ["a"])  # too few vertices for any hull


# -- NumPy references ----------------------------------------------------------------------------

def random_collider(seed, skin=0.0, friction=0.3, restitution=0.2, spheres=3):
    """Overlapping hulls of seeded Gaussian blobs and a few spheres."""
    rng = np.random.default_rng(seed)
    normals, offsets, starts = [], [], [0]
    for _ in range(5):
        pts = rng.normal(size=(int(rng.integers(30, 200)), 3)) * rng.uniform(0.1, 0.4, 3) + rng.uniform(-0.4, 0.4, 3)
        n, b = hull_planes(pts, max_faces=int(rng.integers(8, 40)), inflate=0.003)
        normals.append(n)
        offsets.append(b)
        starts.append(starts[-1] + n.shape[0])
    return HullCollider(np.concatenate(normals), np.concatenate(offsets), starts,
                        rng.uniform(-0.5, 0.5, (spheres, 3)), rng.uniform(0.1, 0.3, spheres), skin=skin, friction=friction, restitution=restitution)


def ref_signed_distance(c, p):
    out = np.full(p.shape[0], np.inf)
    for i, x in enumerate(p):
        for k in range(c.hull_count):
            s, e = c.hull_start[k], c.hull_start[k + 1]
            m = (c.normals[s:e] @ x - c.offsets[s:e]).max()
            if m <= 0:
                d = m
            else:
                t = c.tris[c.tri_start[k]:c.tri_start[k + 1]]
                q, _ = naive_collide.closest_on_triangles(x, c.tri_verts[t[:, 0]], c.tri_verts[t[:, 1]],
                                                          c.tri_verts[t[:, 2]])
                d = np.linalg.norm(q - x, axis=1).min()
            out[i] = min(out[i], d)
        for cs, r in zip(c.sphere_centres, c.sphere_radii):
            out[i] = min(out[i], np.linalg.norm(x - cs) - r)
    return out


@pytest.mark.parametrize("spheres", [3, 0])
def test_signed_distance_against_reference(spheres):
    c = random_collider(1, spheres=spheres)
    p = np.random.default_rng(2).uniform(-1.2, 1.2, (400, 3))
    np.testing.assert_allclose(c.signed_distance(p), ref_signed_distance(c, p), rtol=0, atol=1e-12)


def ref_project(c, x, xp, inv_mass, tol=1e-12):
    """The kernel's rule written plainly: candidate directions, march through the union, nearest."""
    nrm, off = c.normals, c.offsets + c.skin
    hulls = [(nrm[c.hull_start[k]:c.hull_start[k + 1]], off[c.hull_start[k]:c.hull_start[k + 1]])
             for k in range(c.hull_count)]
    spheres = list(zip(c.sphere_centres, c.sphere_radii + c.skin))

    def depth(k, p):
        if k < len(hulls):
            return (hulls[k][0] @ p - hulls[k][1]).max()
        cs, r = spheres[k - len(hulls)]
        return np.linalg.norm(p - cs) - r

    def exit_along(k, p, d):
        if k < len(hulls):
            n, b = hulls[k]
            nd = n @ d
            t = np.where(nd > 0, (b - n @ p) / np.where(nd > 0, nd, 1.0), np.inf)
            j = int(np.argmin(t))
            return max(t[j], 0.0), n[j]
        cs, r = spheres[k - len(hulls)]
        e = p - cs
        t = max(-(e @ d) + math.sqrt(max((e @ d) ** 2 - e @ e + r * r, 0.0)), 0.0)
        return t, (e + t * d) / r

    def march(p, d, t):
        g = d
        while True:
            inside = [k for k in range(len(hulls) + len(spheres)) if depth(k, p + t * d) < -tol]
            if not inside:
                return t, g
            dt, g = exit_along(inside[0], p + t * d, d)
            t += dt

    x, xp = x.copy(), xp.copy()
    for i in np.flatnonzero(inv_mass > 0):
        p = x[i].copy()
        inside = [k for k in range(len(hulls) + len(spheres)) if depth(k, p) < -tol]
        if not inside:
            continue
        options = []
        for k in inside:
            if k < len(hulls):
                n, b = hulls[k]
                j = int(np.argmax(n @ p - b))
                d, t0 = n[j], b[j] - n[j] @ p
            else:
                cs, r = spheres[k - len(hulls)]
                d = (p - cs) / np.linalg.norm(p - cs)
                t0 = r - np.linalg.norm(p - cs)
            t, g = march(p, d, t0)
            options.append((t, t > t0, d, g))
        best = min(options, key=lambda o: o[0])
        if best[1]:
            for k in inside:
                if k < len(hulls):
                    for n, b in zip(*hulls[k]):
                        t, g = march(p, n, b - n @ p)
                        options.append((t, True, n, g))
        t, _, d, g = min(options, key=lambda o: o[0])
        v = x[i] - xp[i]
        vn = v @ g
        vt = v - vn * g
        if vn < 0:
            vn = -c.restitution * vn
        x[i] = p + t * d
        xp[i] = x[i] - ((1 - c.friction) * vt + vn * g)
    return x, xp


def test_project_against_reference_and_nothing_left_inside():
    c = random_collider(3, skin=0.004)
    rng = np.random.default_rng(4)
    x = rng.uniform(-1.0, 1.0, (600, 3))
    xp = x + rng.normal(scale=0.01, size=x.shape)
    inv_mass = (rng.random(600) > 0.1).astype(float)
    rx, rxp = ref_project(c, x, xp, inv_mass)
    inside_before = c.signed_distance(x) < 0
    assert inside_before.sum() > 100  # the test exercises pushes, overlaps included
    x1, xp1 = x.copy(), xp.copy()
    c.project(x1, xp1, inv_mass)
    np.testing.assert_allclose(x1, rx, rtol=0, atol=1e-10)
    np.testing.assert_allclose(xp1, rxp, rtol=0, atol=1e-10)
    free = inv_mass > 0
    assert c.signed_distance(x1[free]).min() >= c.skin - 1e-9
    assert np.array_equal(x1[~free], x[~free])
    # determinism: same bytes on a second run
    x2, xp2 = x.copy(), xp.copy()
    c.project(x2, xp2, inv_mass)
    assert x2.tobytes() == x1.tobytes() and xp2.tobytes() == xp1.tobytes()


# -- fit -----------------------------------------------------------------------------------------

@pytest.mark.parametrize("seed", [0, 1, 2])
def test_hull_inflation_contains_every_segment_vertex_random(seed):
    rng = np.random.default_rng(seed)
    k = 4
    v = np.concatenate([rng.normal(size=(300, 3)) * rng.uniform(0.02, 0.2, 3) + rng.uniform(-0.3, 0.3, 3)
                        for _ in range(k)])
    labels = np.repeat(np.arange(k), 300)
    inflate, max_faces = 0.003, 24
    c = fit_hulls(v, labels, [f"s{j}" for j in range(k)], max_faces=max_faces, inflate=inflate, skin=0.0)
    assert c.parts == [f"s{j}" for j in range(k)] and c.sphere_count == 0
    assert np.all(np.diff(c.hull_start) <= max_faces)
    for j in range(k):
        s, e = c.hull_start[j], c.hull_start[j + 1]
        depth = (v[labels == j] @ c.normals[s:e].T - c.offsets[s:e]).max(axis=1)
        assert depth.max() <= -inflate + 1e-12
        assert depth.max() == pytest.approx(-inflate, abs=1e-12)  # pushed exactly to the farthest vertex


def test_small_hull_kept_whole_and_tiny_segments_skipped():
    cube = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)], float)
    face_centres = np.vstack([0.5 + 0.5 * AXES])
    pts = np.concatenate([cube, face_centres, np.random.default_rng(0).uniform(0.1, 0.9, (10, 3))])
    v = np.concatenate([pts, np.random.default_rng(1).normal(size=(10, 3))])
    c = fit_hulls(v, np.r_[np.zeros(24, int), np.ones(10, int)], ["cube", "few"], inflate=0.0, skin=0.0)
    assert c.parts == ["cube"]
    # under the budget: QuickHull's 12 triangles, coplanar pairs merged into the cube's 6 planes
    assert c.normals.shape[0] == 6
    assert c.signed_distance(np.array([[0.5, 0.5, 0.5]]))[0] == pytest.approx(-0.5, abs=1e-12)


def test_joint_sphere_between_two_halves_of_a_sphere():
    m = trimesh.creation.icosphere(subdivisions=3, radius=0.1)
    v, f = np.asarray(m.vertices), np.asarray(m.faces, dtype=np.int64)
    labels = (v[:, 0] > 0).astype(np.int64)
    c = fit_hulls(v, labels, ["left", "right"], body_tris=f, skin=0.0)
    assert c.parts == ["left", "right", "left|right"]
    assert np.linalg.norm(c.sphere_centres[0]) < 0.01
    assert 0.09 < c.sphere_radii[0] < 0.1
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    ring = np.unique(e[labels[e[:, 0]] != labels[e[:, 1]]])
    cm = fit_hulls(v, labels, ["left", "right"], body_tris=f, joint_radius="min")
    assert cm.sphere_radii[0] <= c.sphere_radii[0]
    assert cm.sphere_radii[0] == pytest.approx(np.linalg.norm(v[ring] - v[ring].mean(axis=0), axis=1).min())
    with pytest.raises(InputError):
        fit_hulls(v, labels, ["left", "right"], body_tris=f, joint_radius="max")


def test_surface_samples_on_the_surface_and_seeded():
    c = random_collider(5)
    p, k = c.surface_samples(count_per_part=100, seed=7, exposed=False)
    assert p.shape == (100 * c.count, 3) and k.shape == (100 * c.count,)
    for j in range(c.count):
        assert np.abs(c._part_depth(j, p[k == j])).max() < 1e-9
    pe, ke = c.surface_samples(count_per_part=100, seed=7)
    assert 0 < pe.shape[0] < p.shape[0] and pe.shape[0] == ke.shape[0]
    assert np.abs(c.signed_distance(pe)).max() < 1e-9  # exposed samples lie on the union's boundary
    p2, k2 = c.surface_samples(count_per_part=100, seed=7)
    assert p2.tobytes() == pe.tobytes() and np.array_equal(k2, ke)


def test_real_body_hulls_contain_their_segments(body_model):
    from vfit_engine.body.segment import segment

    verts = body_model.default_verts("female")[:13380]
    seg = segment(body_model, verts)
    inflate = 0.003
    c = fit_hulls(verts, seg.labels, seg.names, body_tris=body_model.body_tris, inflate=inflate)
    assert c.hull_count == len(seg.names) and c.sphere_count >= 14
    assert np.all(np.diff(c.hull_start) <= 64)
    for j, name in enumerate(c.parts[:c.hull_count]):
        s, e = c.hull_start[j], c.hull_start[j + 1]
        pts = verts[seg.labels == seg.names.index(name)]
        assert (pts @ c.normals[s:e].T - c.offsets[s:e]).max() <= -inflate + 1e-12, name
    assert c.signed_distance(verts).max() <= -inflate + 1e-12
    rng = np.random.default_rng(0)
    x = verts[rng.choice(13380, 3000)] + rng.normal(scale=0.02, size=(3000, 3))
    xp = x.copy()
    c.project(x, xp, np.ones(3000))
    assert c.signed_distance(x).min() >= c.skin - 1e-9
    p, k = c.surface_samples()
    assert p.shape[0] == k.shape[0] > 0 and k.max() < c.count


def test_points_in_the_corners_of_the_skinned_hulls_are_pushed_out():
    # the hulls' bounding spheres must hold the skinned hulls, whose corners stick out by more
    # than the skin: points just inside every corner must be found and pushed
    c = random_collider(6, skin=0.02, spheres=0)
    skinned = HullCollider(c.normals, c.offsets + c.skin, c.hull_start, skin=0.0)
    corners = []
    for k in range(c.hull_count):
        t = skinned.tris[skinned.tri_start[k]:skinned.tri_start[k + 1]]
        v = skinned.tri_verts[np.unique(t)]
        corners.append(v + 1e-6 * (v.mean(axis=0) - v))
    x = np.concatenate(corners)
    assert skinned.signed_distance(x).max() < 0
    xp = x.copy()
    c.project(x, xp, np.ones(x.shape[0]))
    assert skinned.signed_distance(x).min() >= -1e-9
