"""Ellipsoid collider: analytic point-vs-ellipsoid cases, kernels against slow NumPy references,
the no-particle-left-inside invariant with overlapping ellipsoids, and a fit on the real body."""
import numpy as np
import pytest

from vfit_engine.collide.ellipsoids import EllipsoidCollider, fit_ellipsoids
from vfit_engine.errors import InputError
from vfit_engine.kernels import collide_ellipsoid as ke


def _rotation(rng):
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[2] *= -1.0
    return q


def _random_set(rng, e, spread=0.3):
    centres = rng.uniform(-spread, spread, size=(e, 3))
    rots = np.array([_rotation(rng) for _ in range(e)])
    axes = rng.uniform(0.08, 0.3, size=(e, 3))
    return centres, rots, axes


# ---------------------------------------------------------------- slow, obvious references

def _ref_local(p, c, rot):
    return rot @ (p - c)


def _ref_dense_distance(y, a, n_theta=500, n_phi=1000):
    """Distance from local point y to the axis-aligned ellipsoid a by dense parametric sampling."""
    th = np.linspace(0.0, np.pi, n_theta)
    ph = np.linspace(0.0, 2.0 * np.pi, n_phi, endpoint=False)
    st, ct = np.sin(th)[:, None], np.cos(th)[:, None]
    s = np.stack([a[0] * st * np.cos(ph), a[1] * st * np.sin(ph), a[2] * ct * np.ones_like(ph)], axis=-1)
    return np.sqrt(((s.reshape(-1, 3) - y) ** 2).sum(axis=1)).min()


def _ref_project(x, xp, inv_mass, centres, rots, axes, cf, cr, max_rounds=4):
    """Radial two-phase projection written plainly (lists of candidates, Python loops)."""
    x, xp = x.copy(), xp.copy()
    e_count = axes.shape[0]

    def level(p, e):
        return float(((_ref_local(p, centres[e], rots[e]) / axes[e]) ** 2).sum())

    def inside(p, e):
        return level(p, e) < 1.0 - ke.LEVEL_TOL

    def radial(p, e):
        y = _ref_local(p, centres[e], rots[e])
        return centres[e] + rots[e].T @ (y / np.sqrt(level(p, e)))

    for i in range(x.shape[0]):
        if inv_mass[i] <= 0 or not any(inside(x[i], e) for e in range(e_count)):
            continue
        p, chosen = x[i].copy(), None
        for _ in range(max_rounds + 1):
            cands = [(np.linalg.norm(radial(p, e) - p), e, radial(p, e)) for e in range(e_count) if inside(p, e)]
            if not cands:
                break
            valid = [c for c in cands if not any(inside(c[2], f) for f in range(e_count) if f != c[1])]
            if valid:
                chosen = min(valid, key=lambda c: c[0])
                break
            best = min(cands, key=lambda c: c[0])
            p, chosen = best[2], None
            last = best
        if chosen is None and any(inside(p, e) for e in range(e_count)):
            # ray from x through p: step to the exit of every ellipsoid the walker is in
            d = (p - x[i]) / np.linalg.norm(p - x[i])
            s, hit = 0.0, -1
            while True:
                stepped = False
                for e in range(e_count):
                    y, w = _ref_local(x[i], centres[e], rots[e]), rots[e] @ d
                    qa, qb, qc = ((w / axes[e]) ** 2).sum(), ((y * w) / axes[e] ** 2).sum(), \
                        ((y / axes[e]) ** 2).sum() - 1
                    disc = qb * qb - qa * qc
                    if disc > 0:
                        lo, hi = (-qb - np.sqrt(disc)) / qa, (-qb + np.sqrt(disc)) / qa
                        if lo <= s < hi:
                            s, hit, stepped = hi, e, True
                if not stepped:
                    break
            chosen = (0.0, hit, x[i] + s * d)
        elif chosen is None:
            chosen = last
        _, e, q = chosen
        yq = _ref_local(q, centres[e], rots[e])
        n = rots[e].T @ (yq / axes[e] ** 2)
        n /= np.linalg.norm(n)
        v = x[i] - xp[i]
        vn = v @ n
        vt = v - vn * n
        if vn < 0:
            vn = -cr * vn
        x[i] = q
        xp[i] = q - ((1 - cf) * vt + vn * n)
    return x, xp


# ---------------------------------------------------------------- analytic cases

def test_sphere_radial_equals_closest():
    rng = np.random.default_rng(1)
    c, rot, r = np.array([[0.1, -0.2, 0.3]]), _rotation(rng)[None], 0.25
    axes = np.full((1, 3), r)
    pts = c + rng.uniform(-0.14, 0.14, size=(200, 3))
    part = np.zeros(200, dtype=np.int64)
    radial = ke.ellipsoid_surface_points(pts, c, rot, axes, part, closest=False)
    closest = ke.ellipsoid_surface_points(pts, c, rot, axes, part, closest=True)
    expect = c + r * (pts - c) / np.linalg.norm(pts - c, axis=1, keepdims=True)
    np.testing.assert_allclose(radial, expect, atol=1e-12)
    np.testing.assert_allclose(closest, expect, atol=1e-12)
    d = ke.ellipsoid_signed_distance(pts, c, rot, axes)
    np.testing.assert_allclose(d, np.linalg.norm(pts - c, axis=1) - r, atol=1e-12)


def test_axis_points_go_to_axis_ends():
    a = np.array([[0.3, 0.2, 0.1]])
    c, rot = np.zeros((1, 3)), np.eye(3)[None]
    part = np.zeros(1, dtype=np.int64)
    for k in range(3):
        for sign in (1.0, -1.0):
            p = np.zeros((1, 3))
            p[0, k] = sign * 0.4 * a[0, k]
            end = np.zeros((1, 3))
            end[0, k] = sign * a[0, k]
            np.testing.assert_allclose(ke.ellipsoid_surface_points(p, c, rot, a, part), end, atol=1e-15)
            # outside on an axis, the closest point is the axis end as well
            np.testing.assert_allclose(ke.ellipsoid_surface_points(3 * p, c, rot, a, part, closest=True), end,
                                       atol=1e-12)
            np.testing.assert_allclose(ke.ellipsoid_signed_distance(3 * p, c, rot, a), [0.2 * a[0, k]], atol=1e-12)
    # inside on the shortest axis the closest point is its end too
    np.testing.assert_allclose(ke.ellipsoid_surface_points([[0, 0, -0.05]], c, rot, a, part, closest=True),
                               [[0, 0, -0.1]], atol=1e-15)
    # ... but inside on the longest axis it is not: closest of (x, 0, 0) is
    # (a0 x/(a0^2-a2^2) a0, 0, a2 sqrt(1 - (a0 x/(a0^2-a2^2))^2)) (Eberly's y2 = 0 branch)
    x = 0.1
    u = a[0, 0] * x / (a[0, 0] ** 2 - a[0, 2] ** 2)
    q = ke.ellipsoid_surface_points([[x, 0, 0]], c, rot, a, part, closest=True)
    np.testing.assert_allclose(q, [[a[0, 0] * u, 0, a[0, 2] * np.sqrt(1 - u * u)]], atol=1e-15)
    np.testing.assert_allclose(ke.ellipsoid_signed_distance([[x, 0, 0]], c, rot, a),
                               [-np.linalg.norm(q[0] - [x, 0, 0])], atol=1e-15)
    # the centre: radial has no direction, the nearest point is the end of the shortest axis
    q0 = ke.ellipsoid_surface_points([[0, 0, 0]], c, rot, a, part)
    assert abs(abs(q0[0, 2]) - 0.1) < 1e-15 and abs(q0[0, :2]).max() == 0.0


def test_closest_point_against_dense_sampling():
    rng = np.random.default_rng(2)
    for a in (np.array([0.3, 0.2, 0.1]), np.array([0.2, 0.2, 0.05]), np.array([0.1, 0.25, 0.12])):
        y = rng.uniform(-1.6, 1.6, size=(40, 3)) * a
        q = np.array([ke.closest_local(*p, *a) for p in y])
        np.testing.assert_allclose(((q / a) ** 2).sum(axis=1), 1.0, atol=1e-12)
        d = np.linalg.norm(q - y, axis=1)
        ref = np.array([_ref_dense_distance(p, a) for p in y])
        # the exact distance is a lower bound of the sampled one and within the sampling gap
        assert np.all(d <= ref + 1e-12)
        np.testing.assert_allclose(d, ref, atol=1e-3 * a.max())
        # optimality: y - q is along the surface normal q / a^2
        n = q / a ** 2
        cross = np.cross(y - q, n) / np.linalg.norm(n, axis=1, keepdims=True)
        assert np.abs(cross).max() < 1e-10


# ---------------------------------------------------------------- the projection kernel

@pytest.mark.parametrize("max_rounds", [0, 4])
def test_projection_matches_numpy_reference(max_rounds):
    rng = np.random.default_rng(3)
    centres, rots, axes = _random_set(rng, 6)
    x = rng.uniform(-0.5, 0.5, size=(400, 3))
    xp = x + rng.normal(scale=0.01, size=x.shape)
    inv_mass = np.where(rng.random(400) < 0.1, 0.0, 1.0)
    cf = np.full(6, 0.3)
    cr = np.full(6, 0.2)
    ref_x, ref_xp = _ref_project(x, xp, inv_mass, centres, rots, axes, 0.3, 0.2, max_rounds)
    got_x, got_xp = x.copy(), xp.copy()
    moved = ke.collide_ellipsoids(got_x, got_xp, inv_mass, centres, rots, axes, cf, cr, max_rounds=max_rounds)
    assert moved > 50
    np.testing.assert_allclose(got_x, ref_x, atol=1e-12)
    np.testing.assert_allclose(got_xp, ref_xp, atol=1e-12)


@pytest.mark.parametrize("closest", [False, True])
def test_no_particle_left_inside_overlapping_ellipsoids(closest):
    rng = np.random.default_rng(4 + closest)
    centres, rots, axes = _random_set(rng, 8, spread=0.15)
    col = EllipsoidCollider(centres, rots, axes, skin=0.0, closest=closest)
    x = rng.uniform(-0.45, 0.45, size=(3000, 3))
    xp = x.copy()
    inv_mass = np.ones(3000)
    inv_mass[:100] = 0.0
    pinned = x[:100].copy()
    before = col.level(x).min(axis=1)
    assert (before[100:] < 1).sum() > 500  # overlaps are really exercised
    col.project(x, xp, inv_mass)
    after = col.level(x).min(axis=1)
    assert after[100:].min() >= 1.0 - 1e-9
    np.testing.assert_array_equal(x[:100], pinned)
    outside = before >= 1.0
    assert np.all(np.isfinite(x))
    # particles already outside are not touched
    np.testing.assert_array_equal(x[outside], xp[outside])
    # with a skin the particles sit outside the inflated set too
    col.skin = 0.02
    col.project(x, xp, inv_mass)
    inflated = EllipsoidCollider(centres, rots, axes * 1.02).level(x[100:]).min(axis=1)
    assert inflated.min() >= 1.0 - 1e-9


def test_velocity_split_friction_restitution():
    c, rot, a = np.zeros((1, 3)), np.eye(3)[None], np.array([[0.2, 0.2, 0.1]])
    # on the +Z pole moving down (into the solid) and sideways along X
    x = np.array([[0.0, 0.0, 0.09]])
    v = np.array([0.01, 0.0, -0.02])
    for cf, cr, expect in ((0.0, 0.0, [0.01, 0, 0]), (1.0, 0.0, [0, 0, 0]), (0.5, 1.0, [0.005, 0, 0.02])):
        xx, xp = x.copy(), x - v
        ke.collide_ellipsoids(xx, xp, np.ones(1), c, rot, a, [cf], [cr])
        np.testing.assert_allclose(xx, [[0, 0, 0.1]], atol=1e-15)
        np.testing.assert_allclose(xx - xp, [expect], atol=1e-15)


def test_projection_is_deterministic():
    rng = np.random.default_rng(5)
    centres, rots, axes = _random_set(rng, 5, spread=0.15)
    x0 = rng.uniform(-0.4, 0.4, size=(1000, 3))
    runs = []
    for _ in range(2):
        x, xp = x0.copy(), x0 - 0.001
        EllipsoidCollider(centres, rots, axes, closest=True).project(x, xp, np.ones(1000))
        runs.append((x.tobytes(), xp.tobytes()))
    assert runs[0] == runs[1]


def test_signed_distance_is_min_over_parts():
    rng = np.random.default_rng(6)
    centres, rots, axes = _random_set(rng, 3)
    col = EllipsoidCollider(centres, rots, axes)
    pts = rng.uniform(-0.5, 0.5, size=(25, 3))
    d = col.signed_distance(pts)
    lev = col.level(pts)
    ref = np.empty(25)
    for i, p in enumerate(pts):
        ref[i] = min((-1 if lev[i, e] < 1 else 1) * _ref_dense_distance(_ref_local(p, centres[e], rots[e]), axes[e],
                                                                        250, 500)
                     for e in range(3))
    np.testing.assert_allclose(d, ref, atol=3e-3)
    assert np.all((d < 0) == (lev.min(axis=1) < 1))


def test_surface_samples():
    rng = np.random.default_rng(7)
    centres, rots, axes = _random_set(rng, 4)
    col = EllipsoidCollider(centres, rots, axes, parts=list("abcd"))
    pts, part = col.surface_samples(150, seed=3)
    assert pts.shape == (600, 3) and part.dtype == np.int64
    np.testing.assert_array_equal(np.bincount(part), [150] * 4)
    lev = col.level(pts)[np.arange(600), part]
    np.testing.assert_allclose(lev, 1.0, atol=1e-12)
    again, _ = col.surface_samples(150, seed=3)
    np.testing.assert_array_equal(pts, again)
    assert not np.array_equal(pts, col.surface_samples(150, seed=4)[0])
    exposed, epart = col.surface_samples(150, seed=3, exposed=True)
    lev = col.level(exposed)
    lev[np.arange(len(epart)), epart] = np.inf
    assert len(epart) <= 600 and lev.min() >= 1.0


# ---------------------------------------------------------------- fitting

def test_fit_recovers_a_sampled_ellipsoid():
    rng = np.random.default_rng(8)
    rot, a, c = _rotation(rng), np.array([0.25, 0.12, 0.06]), np.array([0.1, 1.2, -0.05])
    u = rng.normal(size=(20000, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    pts = c + (u * a) @ rot
    noise = np.vstack([pts, c + (rng.uniform(-0.5, 0.5, size=(30, 3)) * a) @ rot])  # interior points
    labels = np.zeros(len(noise), dtype=np.int64)
    labels[:5] = 1  # a part too small to fit
    col = fit_ellipsoids(noise, labels, ["body", "tiny"], quantile=1.0)
    assert col.parts == ["body"] and col.count == 1
    np.testing.assert_allclose(col.axes[0], a, rtol=0.01)
    np.testing.assert_allclose(col.centres[0], c, atol=0.002)
    np.testing.assert_allclose(np.abs(col.rotations[0] @ rot.T), np.eye(3), atol=0.01)
    assert col.level(noise).max() <= 1.0 + 1e-9
    # a lower quantile leaves about (1 - q) of the vertices outside
    col = fit_ellipsoids(noise, labels, ["body", "tiny"], quantile=0.9)
    frac = np.mean(col.level(noise[labels == 0])[:, 0] < 1.0 + 1e-12)
    assert 0.9 <= frac < 0.95


def test_bad_input():
    pts = np.zeros((30, 3))
    with pytest.raises(InputError):
        fit_ellipsoids(pts, np.zeros(29, dtype=np.int64), ["a"])
    with pytest.raises(InputError):
        fit_ellipsoids(pts, np.zeros(30, dtype=np.int64), ["a"], quantile=0.0)
    with pytest.raises(InputError):
        fit_ellipsoids(pts, np.full(30, 3), ["a"])
    with pytest.raises(InputError):
        EllipsoidCollider([[0, 0, 0]], [np.eye(3)], [[0.1, 0.0, 0.1]])
    with pytest.raises(InputError):
        EllipsoidCollider([[0, 0, 0]], [2 * np.eye(3)], [[0.1, 0.1, 0.1]])
    with pytest.raises(InputError):
        EllipsoidCollider([[0, 0, 0]], [np.eye(3)], [[0.1, 0.1, 0.1]], friction=2.0)


def test_fit_on_default_body(body_model):
    from vfit_engine.body.model import N_BODY
    from vfit_engine.body.segment import segment

    verts = body_model.default_verts("female")
    seg = segment(body_model, verts)
    body = verts[:N_BODY]
    col = fit_ellipsoids(body, seg.labels, seg.names)
    assert col.count == len(seg.names)
    d = col.signed_distance(body)
    inside = float(np.mean(d < 0.0))
    near = float(np.mean(d < 0.005))
    print(f"default female: {inside:.4f} of body vertices inside the ellipsoids, {near:.4f} inside or within 5 mm")
    assert near >= 0.9
