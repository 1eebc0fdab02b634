"""Spheres along the skeleton (vfit_engine.collide.bone_spheres): analytic solids and the real body."""
import time

import numpy as np
import pytest
import trimesh

from vfit_engine.collide.bone_spheres import _point_triangle_distance, fit_bone_spheres, skeleton_bones
from vfit_engine.errors import InputError

# trimesh builds cylinders and cones along +Z; this proper rotation takes Z to Y (keeps the winding)
Z_TO_Y = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


def _along_y(mesh):
    return np.ascontiguousarray(mesh.vertices @ Z_TO_Y.T), np.asarray(mesh.faces, dtype=np.int64)


def _cylinder(r=0.1, h=1.0, n=32):
    return _along_y(trimesh.creation.cylinder(radius=r, height=h, sections=n))


def _axis_bone(y0, y1):
    return [(np.array([0.0, y0, 0.0]), np.array([0.0, y1, 0.0]))]


@pytest.mark.parametrize("n", [6, 32])
def test_cylinder_inscribed_is_inradius(n):
    r = 0.1
    verts, tris = _cylinder(r=r, n=n)
    c, rad, bone_of = fit_bone_spheres(verts, tris, _axis_bone(-0.3, 0.3), per_bone=4, radius="inscribed")
    assert len(rad) == 4
    np.testing.assert_allclose(rad, r * np.cos(np.pi / n), rtol=1e-9)
    np.testing.assert_array_equal(bone_of, 0)


@pytest.mark.parametrize("n", [6, 32])
def test_cylinder_mean_is_perimeter_over_two_pi(n):
    r = 0.1
    verts, tris = _cylinder(r=r, n=n)
    _, rad, _ = fit_bone_spheres(verts, tris, _axis_bone(-0.3, 0.3), per_bone=3, radius="mean")
    perimeter = 2.0 * n * r * np.sin(np.pi / n)
    np.testing.assert_allclose(rad, perimeter / (2.0 * np.pi), rtol=1e-9)


def test_centres_are_evenly_spaced_along_the_bone():
    verts, tris = _cylinder()
    head, tail = np.array([0.0, -0.4, 0.0]), np.array([0.0, 0.4, 0.0])
    for per_bone in (1, 3, 7):
        c, rad, _ = fit_bone_spheres(verts, tris, [(head, tail)], per_bone=per_bone)
        assert len(rad) == per_bone
        t = (np.arange(per_bone) + 0.5) / per_bone
        np.testing.assert_allclose(c, head + t[:, None] * (tail - head), atol=1e-15)


def test_tilted_solid_gives_the_same_radii():
    """Rotating body and bone together changes nothing (the plane follows the bone)."""
    r, n = 0.1, 12
    verts, tris = _cylinder(r=r, n=n)
    rot = trimesh.transformations.random_rotation_matrix(np.random.default_rng(3).random(3))[:3, :3]
    head, tail = np.array([0.0, -0.3, 0.0]), np.array([0.0, 0.3, 0.0])
    c, rad, _ = fit_bone_spheres(verts @ rot.T, tris, [(rot @ head, rot @ tail)], per_bone=5)
    np.testing.assert_allclose(rad, r * np.cos(np.pi / n), rtol=1e-9)
    _, rad_mean, _ = fit_bone_spheres(verts @ rot.T, tris, [(rot @ head, rot @ tail)], per_bone=5, radius="mean")
    np.testing.assert_allclose(rad_mean, n * r * np.sin(np.pi / n) / np.pi, rtol=1e-9)


@pytest.mark.parametrize("extents", [(0.3, 1.0, 0.2), (0.12, 1.0, 0.4)])
def test_box_inscribed_is_half_the_smaller_side(extents):
    box = trimesh.creation.box(extents=extents)
    verts, tris = np.asarray(box.vertices), np.asarray(box.faces, dtype=np.int64)
    _, rad, _ = fit_bone_spheres(verts, tris, _axis_bone(-0.25, 0.25), per_bone=4)
    np.testing.assert_allclose(rad, 0.5 * min(extents[0], extents[2]), rtol=1e-9)


def test_points_outside_the_body_give_no_sphere():
    verts, tris = _cylinder(r=0.1, h=1.0)  # y in [-0.5, 0.5]
    # t = 1/8, 3/8, 5/8, 7/8 of a bone from y = 0 to y = 1.6: y = 0.2, 0.6, 1.0, 1.4 -> only the first is inside
    c, rad, _ = fit_bone_spheres(verts, tris, _axis_bone(0.0, 1.6), per_bone=4)
    np.testing.assert_allclose(c, [[0.0, 0.2, 0.0]], atol=1e-15)
    # beside the cylinder, parallel to its axis
    side = [(np.array([0.3, -0.2, 0.0]), np.array([0.3, 0.2, 0.0]))]
    c, rad, bone_of = fit_bone_spheres(verts, tris, side, per_bone=4)
    assert c.shape == (0, 3) and rad.shape == (0,) and bone_of.shape == (0,)


def test_hollow_tube_uses_every_loop():
    """Inside the hole of a tube is outside the body; in the wall, the inner loop can be the nearer one."""
    r_in, r_out, n = 0.1, 0.2, 64
    verts, tris = _along_y(trimesh.creation.annulus(r_min=r_in, r_max=r_out, height=1.0, sections=n))
    hole = _axis_bone(-0.2, 0.2)
    assert len(fit_bone_spheres(verts, tris, hole)[1]) == 0
    x = 0.13  # nearer the inner wall
    wall = [(np.array([x, -0.2, 0.0]), np.array([x, 0.2, 0.0]))]
    _, rad, _ = fit_bone_spheres(verts, tris, wall, per_bone=2, min_radius=0.0)
    # the section's vertices lie on the circles at angles 2 pi k / n, so x is on a vertex's ray
    np.testing.assert_allclose(rad, x - r_in, rtol=1e-9)
    _, rad_mean, _ = fit_bone_spheres(verts, tris, wall, per_bone=2, radius="mean")
    np.testing.assert_allclose(rad_mean, n * r_out * np.sin(np.pi / n) / np.pi, rtol=1e-9)


def test_clamp_to_the_surface_on_a_cone():
    """Along a cone's axis the section radius overestimates the 3-D distance to the slanted faces."""
    big_r, big_h, n = 0.2, 0.5, 8
    verts, tris = _along_y(trimesh.creation.cone(radius=big_r, height=big_h, sections=n))  # base y=0, apex y=H
    ys = np.array([0.2, 0.25])
    bones = [(np.array([0.0, y - 0.01, 0.0]), np.array([0.0, y + 0.01, 0.0])) for y in ys]
    r_in = big_r * np.cos(np.pi / n)
    in_plane = r_in * (1.0 - ys / big_h)
    _, rad, _ = fit_bone_spheres(verts, tris, bones, per_bone=1, clamp=False)
    np.testing.assert_allclose(rad, in_plane, rtol=1e-9)
    _, rad, _ = fit_bone_spheres(verts, tris, bones, per_bone=1)
    np.testing.assert_allclose(rad, in_plane * big_h / np.hypot(big_h, r_in), rtol=1e-9)


def _naive_point_triangle(p, a, b, c):
    """Distance from p to triangle abc: the plane projection if it falls inside, else the nearest edge."""
    n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n)
    q = p - np.dot(p - a, n) * n
    inside = all(np.dot(np.cross(v1 - v0, q - v0), n) >= 0 for v0, v1 in ((a, b), (b, c), (c, a)))
    if inside:
        return float(np.linalg.norm(p - q))

    def seg(u, w):
        t = np.clip(np.dot(p - u, w - u) / np.dot(w - u, w - u), 0.0, 1.0)
        return float(np.linalg.norm(p - (u + t * (w - u))))

    return min(seg(a, b), seg(b, c), seg(c, a))


def test_point_triangle_distance_matches_reference():
    rng = np.random.default_rng(11)
    tri = rng.normal(size=(500, 3, 3))
    p = rng.normal(size=3) * 1.5
    got = _point_triangle_distance(p, tri[:, 0], tri[:, 1], tri[:, 2])
    want = [_naive_point_triangle(p, *t) for t in tri]
    np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-12)


def test_min_radius_drops_small_spheres_and_is_deterministic():
    verts, tris = _cylinder(r=0.1, n=32)
    bones = _axis_bone(-0.3, 0.3)
    assert len(fit_bone_spheres(verts, tris, bones, min_radius=0.11)[1]) == 0
    a = fit_bone_spheres(verts, tris, bones, per_bone=5)
    b = fit_bone_spheres(verts, tris, bones, per_bone=5)
    for x, y in zip(a, b):
        assert x.tobytes() == y.tobytes()


@pytest.mark.parametrize("kwargs", [dict(radius="max"), dict(per_bone=0), dict(per_bone=2.5), dict(min_radius=-1.0)])
def test_bad_options_raise(kwargs):
    verts, tris = _cylinder()
    with pytest.raises(InputError):
        fit_bone_spheres(verts, tris, _axis_bone(-0.3, 0.3), **kwargs)


def test_bad_bones_raise():
    verts, tris = _cylinder()
    with pytest.raises(InputError):
        fit_bone_spheres(verts, tris, _axis_bone(0.1, 0.1))
    with pytest.raises(InputError):
        fit_bone_spheres(verts, tris, [(np.zeros(3), np.array([0.0, np.nan, 0.0]))])
    with pytest.raises(InputError):
        fit_bone_spheres(verts, tris, [np.zeros(3)])


# ------------------------------------------------------------------ the real body
@pytest.fixture(scope="module")
def real_body(body_model):
    # conftest's body model: a broken loader fails here instead of showing as a skip
    return body_model, body_model.default_verts("female")


def test_skeleton_bones_of_the_default_body(real_body):
    bm, verts = real_body
    bones = skeleton_bones(bm, verts)
    lengths = np.array([np.linalg.norm(t - h) for h, t in bones])
    assert len(bones) > 60 and lengths.min() >= 0.01
    assert all(h.shape == (3,) and t.shape == (3,) for h, t in bones)


def test_real_body_inscribed_spheres_lie_inside(real_body):
    from vfit_engine.collide.body_mesh import MeshCollider

    bm, verts = real_body
    body = verts[:13380]
    bones = skeleton_bones(bm, verts)
    t0 = time.perf_counter()
    centres, radii, bone_of = fit_bone_spheres(body, bm.body_tris, bones, per_bone=4)
    elapsed = time.perf_counter() - t0
    print(f"\nbone spheres (inscribed, per_bone=4): {len(radii)} spheres on {len(bones)} bones in {elapsed:.2f} s")
    assert len(radii) > 100
    assert radii.min() >= 0.008 and bone_of.min() >= 0 and bone_of.max() < len(bones)
    d = MeshCollider(body, bm.body_tris).query(centres, max_out=0.0, max_in=1.0)[0]
    assert np.all(d < 0.0)
    assert np.all(-d >= radii - 1e-6)
