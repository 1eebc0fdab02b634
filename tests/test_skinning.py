"""LBS and DQS skinning: kernels against slow NumPy references, rigid invariants on the real body,
the candy-wrapper cylinder, and bad input."""
import numpy as np
import pytest

from vfit_engine.body.skinning import Skinning
from vfit_engine.rotations import dual_quat_to_rigid, quat_to_rotation, rigid_to_dual_quat
from vfit_engine.kernels import skinning as kernels


# ---------------------------------------------------------------------- helpers and references
def _random_rigid(rng, count, scale=0.3):
    """(count, 3, 4) ``[R | t]`` with uniformly random rotations and translations ~ ``scale`` m."""
    mats = np.empty((count, 3, 4))
    mats[:, :, :3] = quat_to_rotation(rng.normal(size=(count, 4)))
    mats[:, :, 3] = rng.normal(scale=scale, size=(count, 3))
    return mats


def _random_csr(rng, n, bone_count, max_influences=4):
    """Random CSR weights: 0..max_influences distinct bones per vertex, weights > 0 summing to 1."""
    counts = rng.integers(0, max_influences + 1, size=n)
    offsets = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(counts, out=offsets[1:])
    bones = np.concatenate([rng.choice(bone_count, c, replace=False) for c in counts]).astype(np.int64)
    raw = rng.uniform(0.05, 1.0, size=offsets[-1])
    sums = np.add.reduceat(raw, offsets[:-1][counts > 0])
    weights = raw / np.repeat(sums, counts[counts > 0])
    return offsets, bones, weights


def _lbs_reference(rest, offsets, bones, weights, mats):
    out = rest.copy()
    for i in range(len(rest)):
        ks = range(offsets[i], offsets[i + 1])
        if len(ks):
            out[i] = sum(weights[k] * (mats[bones[k], :, :3] @ rest[i] + mats[bones[k], :, 3]) for k in ks)
    return out


def _dqs_reference(rest, offsets, bones, weights, real, dual):
    out = rest.copy()
    for i in range(len(rest)):
        ks = np.arange(offsets[i], offsets[i + 1])
        if len(ks):
            r, d = real[bones[ks]], dual[bones[ks]]
            sign = np.where(r @ real[bones[ks[0]]] < 0, -1.0, 1.0)
            w = (weights[ks] * sign)[:, None]
            rot, t = dual_quat_to_rigid((w * r).sum(axis=0), (w * d).sum(axis=0))
            out[i] = rot @ rest[i] + t
    return out


@pytest.fixture(scope="module")
def skinning(body_model):
    return Skinning.from_model(body_model)


@pytest.fixture(scope="module")
def rest_body(body_model):
    return body_model.default_verts("female")


def _tiled(mat, count):
    return np.ascontiguousarray(np.broadcast_to(mat, (count,) + mat.shape))


# ---------------------------------------------------------------------- kernels vs references
def test_lbs_kernel_matches_reference():
    rng = np.random.default_rng(11)
    rest = rng.normal(size=(300, 3))
    offsets, bones, weights = _random_csr(rng, 300, 9)
    mats = _random_rigid(rng, 9)
    out = np.empty_like(rest)
    kernels.lbs(rest, offsets, bones, weights, mats, out)
    np.testing.assert_allclose(out, _lbs_reference(rest, offsets, bones, weights, mats), rtol=0, atol=1e-10)
    assert np.array_equal(out[offsets[:-1] == offsets[1:]], rest[offsets[:-1] == offsets[1:]])


def test_dqs_kernel_matches_reference_and_ignores_quaternion_sign():
    rng = np.random.default_rng(12)
    rest = rng.normal(size=(300, 3))
    offsets, bones, weights = _random_csr(rng, 300, 9)
    mats = _random_rigid(rng, 9)
    real, dual = rigid_to_dual_quat(mats[:, :, :3], mats[:, :, 3])
    out = np.empty_like(rest)
    kernels.dqs(rest, offsets, bones, weights, real, dual, out)
    np.testing.assert_allclose(out, _dqs_reference(rest, offsets, bones, weights, real, dual), rtol=0, atol=1e-10)
    # q and -q are one rotation: flipping some bones' dual quaternions must change nothing
    flip = np.where(rng.random(9) < 0.5, -1.0, 1.0)[:, None]
    flipped = np.empty_like(rest)
    kernels.dqs(rest, offsets, bones, weights, real * flip, dual * flip, flipped)
    np.testing.assert_allclose(flipped, out, rtol=0, atol=1e-12)


# ---------------------------------------------------------------------- the real rig
def test_model_weights_normalised_largest_first(body_model, skinning):
    counts = np.diff(skinning.offsets)
    assert skinning.offsets[-1] == len(body_model.skin[0])
    assert counts.min() >= 1 and len(counts) == 19158
    np.testing.assert_allclose(np.add.reduceat(skinning.weights, skinning.offsets[:-1]), 1.0, rtol=0, atol=1e-13)
    np.testing.assert_allclose(skinning.weight_sums, 1.0, rtol=0, atol=1e-7)  # float32 data
    firsts = skinning.weights[skinning.offsets[:-1]]
    assert np.all(firsts == np.maximum.reduceat(skinning.weights, skinning.offsets[:-1]))


@pytest.mark.parametrize("method", ["lbs", "dqs"])
def test_identity_returns_rest_exactly(skinning, rest_body, method):
    out = skinning.deform(rest_body, _tiled(np.eye(4), skinning.bone_count), method)
    assert np.array_equal(out, rest_body)


@pytest.mark.parametrize("method", ["lbs", "dqs"])
def test_one_transform_for_all_bones_moves_body_rigidly(skinning, rest_body, method):
    mat = _random_rigid(np.random.default_rng(13), 1)[0]
    mats = _tiled(mat, skinning.bone_count)
    if method == "dqs":
        mats = _tiled(np.vstack([mat, [0.0, 0.0, 0.0, 1.0]]), skinning.bone_count)  # 4x4 form
    out = skinning.deform(rest_body, mats, method)
    np.testing.assert_allclose(out, rest_body @ mat[:, :3].T + mat[:, 3], rtol=0, atol=1e-12)


@pytest.mark.parametrize("method", ["lbs", "dqs"])
def test_one_bone_rotation_moves_its_vertices_rigidly(skinning, rest_body, method):
    single = np.diff(skinning.offsets) == 1
    owner = skinning.bones[skinning.offsets[:-1]]
    bone = np.bincount(owner[single], minlength=skinning.bone_count).argmax()
    idx = np.flatnonzero(single & (owner == bone))
    assert len(idx) > 50
    mats = _tiled(np.eye(4), skinning.bone_count)
    pivot = rest_body[idx].mean(axis=0)
    rot = quat_to_rotation(np.array([np.cos(0.4), 0.3, 0.8, -0.5]))
    mats[bone, :3, :3] = rot
    mats[bone, :3, 3] = pivot - rot @ pivot + [0.02, -0.01, 0.03]
    out = skinning.deform(rest_body, mats, method)
    sub = idx[:: max(1, len(idx) // 150)]

    def dists(p):
        return np.linalg.norm(p[:, None] - p[None], axis=-1)

    assert np.abs(out[sub] - rest_body[sub]).max() > 0.01  # they did move
    np.testing.assert_allclose(dists(out[sub]), dists(rest_body[sub]), rtol=0, atol=1e-9)
    vertex_of = np.repeat(np.arange(skinning.vertex_count), np.diff(skinning.offsets))
    untouched = np.ones(skinning.vertex_count, dtype=bool)
    untouched[vertex_of[skinning.bones == bone]] = False
    assert np.array_equal(out[untouched], rest_body[untouched])  # all their bones are the identity


# ---------------------------------------------------------------------- candy wrapper
def _twisted_cylinder(method, twist_deg=150.0):
    """Cylinder r = 1, z in [-2, 2]: bone 0 fixed, bone 1 twisted about z; weights blend over |z| < 1."""
    z = np.linspace(-2.0, 2.0, 41)
    phi = np.linspace(0.0, 2 * np.pi, 48, endpoint=False)
    zz, pp = np.meshgrid(z, phi, indexing="ij")
    rest = np.stack([np.cos(pp).ravel(), np.sin(pp).ravel(), zz.ravel()], axis=1)
    w1 = np.clip((rest[:, 2] + 1.0) / 2.0, 0.0, 1.0)
    n = len(rest)
    skin = Skinning(np.repeat([0, 1], n), np.tile(np.arange(n), 2), np.concatenate([1.0 - w1, w1]), n, 2)
    a = np.radians(twist_deg)
    mats = _tiled(np.eye(4), 2)
    mats[1, :2, :2] = [[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]]
    out = skin.deform(rest, mats, method)
    return rest, out, np.isclose(rest[:, 2], 0.0)


def test_lbs_collapses_at_the_twisted_joint():
    rest, out, mid = _twisted_cylinder("lbs")
    radius = np.linalg.norm(out[mid, :2], axis=1).mean()
    assert radius < 0.5
    assert radius == pytest.approx(np.cos(np.radians(75.0)), abs=1e-9)


def test_dqs_keeps_the_radius_at_the_twisted_joint():
    rest, out, mid = _twisted_cylinder("dqs")
    radius = np.linalg.norm(out[mid, :2], axis=1)
    assert abs(radius.mean() - 1.0) < 0.02
    np.testing.assert_allclose(np.linalg.norm(out[:, :2], axis=1), 1.0, rtol=0, atol=1e-12)
    turn = np.degrees(np.arctan2(out[mid, 1], out[mid, 0]) - np.arctan2(rest[mid, 1], rest[mid, 0])) % 360
    np.testing.assert_allclose(turn, 75.0, atol=1e-9)  # half the twist, half-way along


# ---------------------------------------------------------------------- bad input
def test_out_may_alias_rest(skinning, rest_body):
    mats = _random_rigid(np.random.default_rng(14), skinning.bone_count, 0.01)
    for method in ("lbs", "dqs"):
        expected = skinning.deform(rest_body, mats, method)
        buf = rest_body.copy()
        assert skinning.deform(buf, mats, method, out=buf) is buf
        assert np.array_equal(buf, expected)


@pytest.mark.parametrize("case, method, match", [
    ("nan", "lbs", "bone_mats contains NaN"),
    ("nan", "dqs", "bone_mats contains NaN"),
    ("shape33", "lbs", "bone_mats must have shape"),
    ("bones", "lbs", "bone_mats must have shape"),
    ("rest", "lbs", "rest_verts must have shape"),
    ("scale", "dqs", r"bone_mats\[7\] is not rigid"),
    ("shear", "dqs", r"bone_mats\[7\] is not rigid"),
    ("reflect", "dqs", r"bone_mats\[7\] is not rigid"),
    ("lastrow", "lbs", r"bone_mats\[7\] is not affine"),
    ("out", "lbs", "out must be"),
    ("ok", "slerp", "method must be"),
])
def test_bad_input_raises(skinning, rest_body, case, method, match):
    mats, rest, out = _tiled(np.eye(4), skinning.bone_count), rest_body, None
    if case == "nan":
        mats[3, 0, 1] = np.nan
    elif case == "shape33":
        mats = mats[:, :3, :3]
    elif case == "bones":
        mats = mats[:-1]
    elif case == "rest":
        rest = rest_body[:-1]
    elif case == "scale":
        mats[7, :3, :3] *= 1.1
    elif case == "shear":
        mats[7, 0, 1] = 0.01
    elif case == "reflect":
        mats[7, 0, 0] = -1.0
    elif case == "lastrow":
        mats[7, 3, 0] = 0.5
    elif case == "out":
        out = np.empty((len(rest_body), 3), dtype=np.float32)
    with pytest.raises(ValueError, match=match):
        skinning.deform(rest, mats, method, out=out)


def test_non_rigid_matrix_is_fine_for_lbs(skinning, rest_body):
    mats = _tiled(np.eye(4), skinning.bone_count)
    mats[:, :3, :3] *= 1.5
    np.testing.assert_allclose(skinning.deform(rest_body, mats, "lbs"), 1.5 * rest_body, rtol=0, atol=1e-12)
