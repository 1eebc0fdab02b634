"""Preview pictures: the rasterizer against a slow reference, known cases, colour maps, the PNG."""
from pathlib import Path

import numpy as np
import pytest

from vfit_engine import preview, preview_text
from vfit_engine.errors import InputError
from vfit_engine.kernels.raster import downsample, rasterize
from vfit_engine.preview import COLOUR_MAPS, colour_map, render_image, render_views, value_range

SKIRT = Path(__file__).resolve().parents[1] / "data" / "garments" / "skirt.obj"


# ---------------------------------------------------------------------------------------------
# the rasterizer kernel

def _reference_raster(xyz, tris, colours, gain, h, w):
    """Slow and obvious: every triangle against every sample centre, edge functions written out.

    Same conventions as the kernel: samples at (col + 0.5, row + 0.5), y down, larger depth
    nearer, top-left fill rule. Returns the image, the depth and how many triangles covered each
    sample (the fill rule makes triangles sharing an edge cover each sample on it once).
    """
    image, depth = np.zeros((h, w, 3)), np.full((h, w), -np.inf)
    count = np.zeros((h, w), dtype=np.int64)
    py, px = np.mgrid[0:h, 0:w] + 0.5
    for t, tri in enumerate(tris):
        p = xyz[tri]
        area2 = (p[1, 0] - p[0, 0]) * (p[2, 1] - p[0, 1]) - (p[1, 1] - p[0, 1]) * (p[2, 0] - p[0, 0])
        if area2 == 0:
            continue
        if area2 < 0:
            tri, p, area2 = tri[[0, 2, 1]], p[[0, 2, 1]], -area2
        inside, weights = np.ones((h, w), dtype=bool), []
        for k in range(3):  # the edge a -> b opposite vertex k
            a, b = p[(k + 1) % 3], p[(k + 2) % 3]
            e = (b[0] - a[0]) * (py - a[1]) - (b[1] - a[1]) * (px - a[0])
            dx, dy = b[0] - a[0], b[1] - a[1]
            owns = dy < 0 or (dy == 0 and dx > 0)  # left edge, or top edge
            inside &= (e > 0) | ((e == 0) & owns)
            weights.append(e / area2)
        z = sum(weights[k] * p[k, 2] for k in range(3))
        count += inside
        win = inside & (z > depth)
        depth[win] = z[win]
        rgb = sum(weights[k][..., None] * colours[tri[k]] for k in range(3))
        image[win] = gain[t] * rgb[win]
    return image, depth, count


def _run_kernel(xyz, tris, colours, gain, h, w):
    image, depth = np.zeros((h, w, 3)), np.full((h, w), -np.inf)
    rasterize(np.ascontiguousarray(xyz, dtype=np.float64), np.ascontiguousarray(tris, dtype=np.int64),
              np.ascontiguousarray(colours, dtype=np.float64), np.ascontiguousarray(gain, dtype=np.float64),
              image, depth)
    return image, depth


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_rasterize_matches_reference_on_random_triangles(seed):
    rng = np.random.default_rng(seed)
    h, w, n = 48, 64, 30
    xyz = np.column_stack([rng.uniform(-10, w + 10, n), rng.uniform(-10, h + 10, n), rng.uniform(-1, 1, n)])
    tris = np.array([rng.choice(n, 3, replace=False) for _ in range(25)])
    # collinear (zero area) triangles cover nothing
    xyz[27] = 0.5 * (xyz[25] + xyz[26])
    tris = np.vstack([tris, [[25, 26, 27]]])
    colours, gain = rng.uniform(0, 1, (n, 3)), rng.uniform(0.3, 1, len(tris))
    img, dep = _run_kernel(xyz, tris, colours, gain, h, w)
    ref_img, ref_dep, _ = _reference_raster(xyz, tris, colours, gain, h, w)
    covered = np.isfinite(ref_dep)
    assert covered.sum() > 0.3 * h * w
    np.testing.assert_array_equal(np.isfinite(dep), covered)
    np.testing.assert_allclose(dep[covered], ref_dep[covered], rtol=0, atol=1e-12)
    np.testing.assert_allclose(img, ref_img, rtol=0, atol=1e-12)


def test_square_covers_its_area_once_with_the_top_left_rule():
    # corners on sample centres: the left and top edges take their samples, the right and bottom
    # ones do not, so 10 x 10 samples; the diagonal's samples go to one triangle only
    xyz = np.array([[2.5, 2.5, 0.0], [12.5, 2.5, 0.0], [12.5, 12.5, 0.0], [2.5, 12.5, 0.0]])
    xyz[:, 2] = [1.0, 1.0, 1.0, 1.0]
    tris = np.array([[0, 1, 2], [0, 2, 3]])
    colours = np.array([[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0], [1.0, 1.0, 1.0]])
    img, dep = _run_kernel(xyz, tris, colours, np.ones(2), 16, 16)
    expected = np.zeros((16, 16), dtype=bool)
    expected[2:12, 2:12] = True
    np.testing.assert_array_equal(np.isfinite(dep), expected)
    _, _, count = _reference_raster(xyz, tris, colours, np.ones(2), 16, 16)
    np.testing.assert_array_equal(count, expected.astype(int))
    # the second triangle nearer: it must not win the diagonal, which belongs to the first
    tris2 = np.array([[0, 1, 2], [4, 5, 6]])
    xyz2 = np.vstack([xyz, xyz[[0, 2, 3]] + [0, 0, 1.0]])
    img2, dep2 = _run_kernel(xyz2, tris2, np.vstack([colours, colours[:3]]), np.ones(2), 16, 16)
    ref_img2, ref_dep2, _ = _reference_raster(xyz2, tris2, np.vstack([colours, colours[:3]]), np.ones(2), 16, 16)
    np.testing.assert_allclose(dep2, ref_dep2, rtol=1e-15)
    assert np.isclose(dep2, 2.0).sum() == 45 and np.isclose(dep2, 1.0).sum() == 55


def test_big_triangle_covers_about_its_area():
    xyz = np.array([[3.2, 5.7, 0.0], [181.4, 20.3, 0.0], [60.9, 140.6, 0.0]])
    _, dep = _run_kernel(xyz, np.array([[0, 1, 2]]), np.zeros((3, 3)), np.ones(1), 150, 200)
    area = 0.5 * abs(np.cross(xyz[1] - xyz[0], xyz[2] - xyz[0])[2])
    perimeter = sum(np.linalg.norm(xyz[k, :2] - xyz[k - 1, :2]) for k in range(3))
    assert abs(np.isfinite(dep).sum() - area) < 0.5 * perimeter


@pytest.mark.parametrize("near_first", [True, False])
def test_nearer_triangle_hides_the_farther_one_in_either_order(near_first):
    far = [[0, 0, -0.3], [30, 0, -0.3], [0, 30, -0.3]]
    near = [[5, 5, 0.2], [35, 5, 0.2], [5, 35, 0.2]]
    xyz = np.array(near + far if near_first else far + near, dtype=float)
    colours = np.array([[0, 1.0, 0]] * 3 + [[1.0, 0, 0]] * 3) if near_first else \
        np.array([[1.0, 0, 0]] * 3 + [[0, 1.0, 0]] * 3)
    img, dep = _run_kernel(xyz, np.array([[0, 1, 2], [3, 4, 5]]), colours, np.ones(2), 40, 40)
    both = (dep > -np.inf) & (np.arange(40)[None, :] >= 5) & (np.arange(40)[:, None] >= 5)
    both &= (np.arange(40)[None, :] + np.arange(40)[:, None] + 1 < 30)  # inside the far one too
    assert both.sum() > 100
    np.testing.assert_allclose(img[both], np.tile([0, 1.0, 0], (both.sum(), 1)), atol=1e-12)
    np.testing.assert_allclose(dep[both], 0.2, rtol=1e-15)


def test_cloth_a_millimetre_off_the_skin_hides_it_and_skin_through_it_shows():
    """Two crossing surfaces 1 m from the origin: each wins exactly where it is nearer."""
    # "skin" flat at depth 1.0 m; "cloth" tilted from 1 mm in front (left) to 1 mm behind (right)
    xyz = np.array([[0, 0, 1.0], [64, 0, 1.0], [64, 32, 1.0], [0, 32, 1.0],
                    [0, 0, 1.001], [64, 0, 0.999], [64, 32, 0.999], [0, 32, 1.001]])
    colours = np.array([[1.0, 0.8, 0.7]] * 4 + [[0.2, 0.4, 0.9]] * 4)
    tris = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]])
    img, dep = _run_kernel(xyz, tris, colours, np.ones(4), 32, 64)
    cloth = img[..., 2] > 0.8
    assert cloth[:, :32].all() and not cloth[:, 32:].any()  # crossing at x = 32


def test_downsample_averages_and_fills_empty_samples_with_background():
    image = np.zeros((4, 4, 3))
    image[0, 0] = [1.0, 1.0, 1.0]
    depth = np.full((4, 4), -np.inf)
    depth[0, 0] = depth[0, 1] = 0.0  # (0, 1) drawn black, (1, 0) and (1, 1) empty
    out = np.empty((2, 2, 3))
    downsample(image, depth, np.array([0.0, 0.0, 0.4]), 2, out)
    np.testing.assert_allclose(out[0, 0], [0.25, 0.25, 0.25 + 0.5 * 0.4])
    np.testing.assert_allclose(out[1, 1], [0, 0, 0.4])


# ---------------------------------------------------------------------------------------------
# colour maps and the colour bar

def test_strain_map_stops_and_clamping():
    positions, stops, default = COLOUR_MAPS["strain"]
    rgb = colour_map([-0.15, 0.0, 0.075, 0.15, 0.4, -1.0], "strain")
    np.testing.assert_allclose(rgb[:4], stops)
    np.testing.assert_allclose(rgb[4], stops[-1])  # beyond +15 %: red
    np.testing.assert_allclose(rgb[5], stops[0])
    np.testing.assert_allclose(colour_map([0.0], "strain")[0], preview.CLOTH_RGB)
    assert default == (-0.15, 0.15)


def test_viridis_map_spans_the_data_or_the_given_range():
    stops = np.asarray(COLOUR_MAPS["viridis"][1])
    values = np.array([3.0, 7.0, 11.0])
    rgb = colour_map(values, "viridis")
    np.testing.assert_allclose(rgb[[0, 2]], stops[[0, -1]])
    np.testing.assert_allclose(rgb[1], stops[4])  # the middle stop
    np.testing.assert_allclose(colour_map([0.0, 20.0], "sequential", vmin=0, vmax=20), stops[[0, -1]])
    # luminance grows monotonically along a sequential map
    lum = np.asarray(colour_map(np.linspace(0, 1, 50), "viridis", 0, 1)) @ [0.2126, 0.7152, 0.0722]
    assert np.all(np.diff(lum) > 0)
    assert value_range([5.0, 5.0], "viridis") == pytest.approx((4.95, 5.05))


def test_bar_ticks_are_in_the_given_unit():
    bar = preview_text.bar_texts("strain", "%", -0.15, 0.15, np.array([-0.02, 0.183]))
    assert [t for _, t in bar["ticks"]] == ["-15 %", "-10 %", "-5 %", "0 %", "5 %", "10 %", "15 %"]
    assert bar["ticks"][0][0] == pytest.approx(-0.15)  # positions stay in the values' units
    assert bar["notes"] == ["max 18.3 %", "min -2.0 %"] and bar["beyond_high"] and not bar["beyond_low"]
    bar = preview_text.bar_texts("ease", "mm", 0.0, 37.0, np.array([0.0, 37.0]))
    assert [t for _, t in bar["ticks"]] == ["0 mm", "10 mm", "20 mm", "30 mm"]
    bar = preview_text.bar_texts("pressure", "kPa", 0.0, 1.3, np.array([0.0, 1.3]))
    assert [t for _, t in bar["ticks"]][:3] == ["0.00 kPa", "0.25 kPa", "0.50 kPa"]


# ---------------------------------------------------------------------------------------------
# whole pictures

def _cylinder(radius, y0, y1, n_around, n_up):
    """A side surface (no caps) around the Y axis: (n, 3) verts and (m, 3) triangles."""
    a = np.linspace(0, 2 * np.pi, n_around, endpoint=False)
    y = np.linspace(y0, y1, n_up)
    verts = np.array([[radius * np.sin(t), h, radius * np.cos(t)] for h in y for t in a])
    tris = []
    for i in range(n_up - 1):
        for j in range(n_around):
            p, q = i * n_around + j, i * n_around + (j + 1) % n_around
            tris += [[p, q, q + n_around], [p, q + n_around, p + n_around]]
    return verts, np.array(tris)


def _skin_and_cloth(image):
    r, b = image[..., 0].astype(float), image[..., 2].astype(float)
    return r > 1.15 * b, b > 1.4 * r


def test_skin_shows_only_where_it_pokes_through_the_cloth():
    body_v, body_t = _cylinder(0.15, 0.0, 1.6, 96, 41)
    cloth_v, cloth_t = _cylinder(0.152, 0.6, 1.2, 60, 13)  # 2 mm off the skin (chords: 0.2 mm)
    img = render_image(body_v, body_t, cloth_v, cloth_t, views=("front",), size=(400, 600), shading="flat")
    skin, cloth = _skin_and_cloth(img)
    rows = np.flatnonzero(cloth.any(axis=1))[3:-3]  # the garment's rows, its hems left aside
    assert skin.sum() > 1000 and len(rows) > 100
    assert not skin[rows].any()
    # push a patch facing the viewer 3 mm into the body: skin must show there
    dented = cloth_v.copy()
    patch = (np.abs(np.arctan2(dented[:, 0], dented[:, 2])) < 0.4) & (np.abs(dented[:, 1] - 0.9) < 0.11)
    dented[patch, 0] *= 0.147 / 0.152
    dented[patch, 2] *= 0.147 / 0.152
    img = render_image(body_v, body_t, dented, cloth_t, views=("front",), size=(400, 600), shading="flat")
    skin, _ = _skin_and_cloth(img)
    assert skin[rows].sum() > 300


def test_png_has_the_requested_size_and_the_same_bytes_twice(tmp_path):
    from PIL import Image

    body_v, body_t = _cylinder(0.15, 0.0, 1.6, 32, 9)
    cloth_v, cloth_t = _cylinder(0.16, 0.6, 1.2, 24, 5)
    strain = np.linspace(-0.1, 0.2, len(cloth_v))
    for size in [(1200, 600), (1500, 750), (777, 401)]:
        out = render_views(tmp_path / f"p{size[0]}.png", body_v, body_t, cloth_v, cloth_t, strain,
                           size=size, title="a test")
        with Image.open(out) as im:
            assert im.size == size and im.mode == "RGB" and im.format == "PNG"
    again = render_views(tmp_path / "again.png", body_v, body_t, cloth_v, cloth_t, strain, size=(777, 401),
                         title="a test")
    assert again.read_bytes() == (tmp_path / "p777.png").read_bytes()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["again.png", "p1200.png", "p1500.png", "p777.png"]


def test_views_zoom_shading_and_garment_alone():
    body_v, body_t = _cylinder(0.15, 0.0, 1.6, 32, 9)
    cloth_v, cloth_t = _cylinder(0.16, 0.6, 1.2, 24, 5)
    full = render_image(body_v, body_t, cloth_v, cloth_t, views=("front",), size=(400, 400))
    zoomed = render_image(body_v, body_t, cloth_v, cloth_t, views=("front",), size=(400, 400),
                          zoom=(0.6, 1.2), shading="flat")
    # framing the garment's heights makes it fill more of the picture
    assert _skin_and_cloth(zoomed)[1].sum() > 2 * _skin_and_cloth(full)[1].sum()
    alone = render_image(None, None, cloth_v, cloth_t, values=np.zeros(len(cloth_v)), cmap="viridis",
                         label="ease", unit="mm", views=("left", "right", "back", "front"), size=(900, 300))
    # no skin in the views (the colour bar at the right holds yellow)
    assert alone.shape == (300, 900, 3) and not _skin_and_cloth(alone[:, :700])[0].any()


def test_real_body_and_shipped_skirt(body_model, tmp_path):
    from PIL import Image

    from vfit_engine.body.model import N_BODY
    from vfit_engine.io.mesh import read_mesh

    body_v = body_model.default_verts("female")[:N_BODY]
    skirt = read_mesh(SKIRT)
    out = render_views(tmp_path / "skirt.png", body_v, body_model.body_tris, skirt.verts, skirt.triangles())
    with Image.open(out) as im:
        img = np.asarray(im)
    skin, cloth = _skin_and_cloth(img)
    assert img.shape == (750, 1500, 3) and skin.sum() > 20000 and cloth.sum() > 5000


def test_text_falls_back_to_the_bitmap_font(monkeypatch):
    from PIL import ImageFont

    if not hasattr(ImageFont, "load_default_imagefont"):
        pytest.skip("this Pillow has no separate bitmap default font")

    def bitmap_only(size=None):
        if size is not None:
            raise ImportError("no FreeType")
        return ImageFont.load_default_imagefont()

    monkeypatch.setattr(ImageFont, "load_default", bitmap_only)
    preview_text.font.cache_clear()
    try:
        body_v, body_t = _cylinder(0.15, 0.0, 1.6, 16, 5)
        img = render_image(body_v, body_t, *_cylinder(0.16, 0.6, 1.2, 16, 3), views=("front",), size=(400, 400))
        bottom = img[-40:].astype(int)  # the caption: dark grey ink (shaded skin is not grey)
        ink = (bottom.sum(axis=2) < 200) & (np.ptp(bottom, axis=2) < 10)
        assert ink.sum() > 20
    finally:
        preview_text.font.cache_clear()


# ---------------------------------------------------------------------------------------------
# bad input

def _good():
    body_v, body_t = _cylinder(0.15, 0.0, 1.6, 16, 5)
    cloth_v, cloth_t = _cylinder(0.16, 0.6, 1.2, 12, 3)
    return dict(body_verts=body_v, body_tris=body_t, garment_verts=cloth_v, garment_tris=cloth_t)


def _nan_garment(a):
    a = a["garment_verts"].copy()
    a[3, 1] = np.nan
    return a


BAD = [
    (lambda a: {"garment_verts": _nan_garment(a)}, "non-finite"),
    (lambda a: {"body_verts": a["body_verts"][:, :2]}, "(n, 3)"),
    (lambda a: {"body_verts": a["body_verts"] * 1000}, "in metres"),
    (lambda a: {"cmap": "jet"}, "unknown colour map"),
    (lambda a: {"garment_tris": a["garment_tris"][:, :2]}, "(m, 3)"),
    (lambda a: {"garment_tris": a["garment_tris"][:0]}, "no triangles"),
    (lambda a: {"garment_verts": np.zeros((0, 3)), "garment_tris": np.zeros((0, 3), int)}, "no triangles"),
    (lambda a: {"body_tris": a["body_tris"] + 1000}, "outside"),
    (lambda a: {"body_tris": a["body_tris"] * 1.0}, "integer"),
    (lambda a: {"body_tris": None}, "both"),
    (lambda a: {"values": np.zeros(5)}, "one number per garment vertex"),
    (lambda a: {"values": np.full(len(a["garment_verts"]), np.nan)}, "non-finite"),
    (lambda a: {"cmap": "jet", "values": np.zeros(len(a["garment_verts"]))}, "unknown colour map"),
    (lambda a: {"vmin": 1.0, "vmax": 0.0, "values": np.zeros(len(a["garment_verts"]))}, "vmin <= vmax"),
    (lambda a: {"views": ("top",)}, "views"),
    (lambda a: {"views": ()}, "views"),
    (lambda a: {"size": (100, 50)}, "size"),
    (lambda a: {"size": "big"}, "size"),
    (lambda a: {"zoom": (3.0, 4.0)}, "no vertex"),
    (lambda a: {"zoom": (1.0, 0.5)}, "ymin < ymax"),
    (lambda a: {"shading": "phong"}, "shading"),
]


@pytest.mark.parametrize("change, words", BAD, ids=[w for _, w in BAD])
def test_bad_input_raises_a_one_line_input_error(tmp_path, change, words):
    args = _good()
    args.update(change(args))
    with pytest.raises(InputError) as err:
        render_views(tmp_path / "bad.png", **args)
    message = str(err.value)
    assert words in message and "\n" not in message
    assert not list(tmp_path.iterdir())


def test_unwritable_path_raises_input_error(tmp_path):
    with pytest.raises(InputError, match="cannot write"):
        render_views(tmp_path / "missing" / "p.png", **_good())


# ---------------------------------------------------------------------------------------------
# animated GIFs

def _gif_frames(path):
    """(size, [(h, w, 3) uint8 frames], info) of a GIF file."""
    from PIL import Image

    with Image.open(path) as im:
        size, info, frames = im.size, dict(im.info), []
        for k in range(im.n_frames):
            im.seek(k)
            frames.append(np.asarray(im.convert("RGB")))
    return size, frames, info


def _gif_blocks(data):
    """(has a global colour table, [has a local colour table] per image) from a GIF's bytes (GIF89a spec)."""
    def table(packed):
        return 3 * 2 ** ((packed & 7) + 1) if packed & 0x80 else 0

    def skip_sub_blocks(i):
        while data[i]:
            i += data[i] + 1
        return i + 1

    assert data[:6] == b"GIF89a"
    i = 13 + table(data[10])
    images = []
    while data[i] != 0x3B:  # trailer
        if data[i] == 0x21:  # extension: label, then sub-blocks
            i = skip_sub_blocks(i + 2)
        else:
            assert data[i] == 0x2C  # image descriptor: position, size, packed; table; LZW code size
            images.append(bool(data[i + 9] & 0x80))
            i = skip_sub_blocks(i + 10 + table(data[i + 9]) + 1)
    return bool(data[10] & 0x80), images


def _falling_cloth(n_frames, drop=0.3):
    """A cylinder of cloth around the body lowered by ``drop`` metres over the frames."""
    cloth_v, cloth_t = _cylinder(0.17, 0.9, 1.3, 24, 5)
    return [cloth_v - [0.0, d, 0.0] for d in np.linspace(0.0, drop, n_frames)], cloth_t


def test_gif_has_every_frame_its_size_and_loops(tmp_path):
    from vfit_engine.animation import write_gif

    body_v, body_t = _cylinder(0.15, 0.0, 1.6, 32, 9)
    frames, cloth_t = _falling_cloth(7)
    strain = np.linspace(-0.1, 0.1, len(frames[0]))
    out = write_gif(tmp_path / "drape.gif", body_v, body_t, frames, cloth_t, strain, size=(420, 360), fps=10)
    size, pictures, info = _gif_frames(out)
    assert size == (420, 360) and len(pictures) == 7 and len(_gif_blocks(out.read_bytes())[1]) == 7
    assert info["loop"] == 0 and info["duration"] == 100
    assert sorted(p.name for p in tmp_path.iterdir()) == ["drape.gif"]  # no temporary file left


def test_gif_garment_moves_on_a_still_body_with_one_palette(tmp_path):
    from vfit_engine.animation import write_gif

    body_v, body_t = _cylinder(0.15, 0.0, 1.6, 32, 9)
    frames, cloth_t = _falling_cloth(5, drop=0.3)
    out = write_gif(tmp_path / "d.gif", body_v, body_t, frames, cloth_t, size=(400, 400),
                    view=("front", "side"))
    _, pictures, _ = _gif_frames(out)
    cloth = [_skin_and_cloth(p)[1] for p in pictures]
    rows = [np.flatnonzero(c.any(axis=1)) for c in cloth]
    # the cloth goes down the picture (rows grow downwards) by about its drop: a fixed camera
    assert rows[-1].mean() - rows[0].mean() > 30
    assert abs(cloth[0].sum() - cloth[-1].sum()) < 0.1 * cloth[0].sum()  # same cloth, moved, not zoomed
    # the body where the cloth never is (the top of the picture) keeps its pixels: no jump, no flicker
    top = slice(0, rows[0].min() - 2)
    for p in pictures[1:]:
        np.testing.assert_array_equal(p[top], pictures[0][top])
    assert _skin_and_cloth(pictures[0][top])[0].sum() > 200
    # one palette: the global colour table, and no frame brings its own
    assert _gif_blocks(out.read_bytes()) == (True, [False] * 5)


def test_gif_values_per_frame_and_garment_alone(tmp_path):
    from vfit_engine.animation import render_frames, write_gif

    frames, cloth_t = _falling_cloth(3)
    values = np.stack([np.full(len(frames[0]), v) for v in (0.0, 5.0, 10.0)])
    pictures = list(render_frames(None, None, np.stack(frames), cloth_t, values, cmap="viridis", unit="mm",
                                  label="ease", size=(300, 300), labels=["a", "b", "c"]))
    assert len(pictures) == 3 and pictures[0].shape == (300, 300, 3)
    # one range for all frames: the cloth's colour changes from frame to frame (dark purple to yellow)
    first, last = pictures[0][:, :200].reshape(-1, 3).astype(int), pictures[-1][:, :200].reshape(-1, 3).astype(int)
    assert (first[:, 2] - first[:, 1] > 60).sum() > 500 and (last[:, 0] - last[:, 2] > 100).sum() > 500
    out = write_gif(tmp_path / "a.gif", None, None, frames, cloth_t, size=(300, 300))
    assert len(_gif_frames(out)[1]) == 3


def test_gif_bar_marks_the_wearable_stretch_like_the_still_preview():
    """The GIF's colour bar takes marks as the still preview's does: a dark line across the bar at the mark's
    value (the fabric's wearable stretch), where the bar without it is coloured."""
    from vfit_engine.animation import render_frames

    verts = np.array([[0, 0, 0], [0.3, 0, 0], [0, 0.5, 0]], dtype=float)
    values = np.array([[0.0, 0.1, 0.2], [0.0, 0.1, 0.2]])
    kw = dict(cmap="stretch", vmin=0.0, vmax=0.2, label="yarn strain", unit="%", view="front", size=(600, 400))
    mark = ((0.1, "10 % wearable"),)
    marked = render_frames(None, None, [verts, verts], [[0, 1, 2]], values, marks=mark, **kw)[1]
    plain = render_frames(None, None, [verts, verts], [[0, 1, 2]], values, **kw)[1]
    for picture, marks, inked in ((marked, mark, True), (plain, (), False)):
        bar = preview_text.bar_texts("yarn strain", "%", 0.0, 0.2, values, marks=marks)
        x0, y0, x1, y1 = preview_text.layout(600, 400, 1, None, bar, footer=True)["bar_box"]
        row = picture[round(y0 + 0.5 * (y1 - y0)), x0:x1].astype(int)
        assert np.all(row.max(axis=1) < 80) == inked and np.all(np.ptp(row, axis=1) > 100) != inked


def _gif_args():
    body_v, body_t = _cylinder(0.15, 0.0, 1.6, 16, 5)
    frames, cloth_t = _falling_cloth(3)
    return dict(body_verts=body_v, body_tris=body_t, frames=frames, garment_tris=cloth_t)


GIF_BAD = [
    (lambda a: {"frames": []}, "non-empty"),
    (lambda a: {"frames": 5}, "non-empty"),
    (lambda a: {"frames": [a["frames"][0], a["frames"][1][:-1]]}, "frames[1] has"),
    (lambda a: {"frames": [a["frames"][0], np.full_like(a["frames"][1], np.nan)]}, "non-finite"),
    (lambda a: {"frames": [a["frames"][0][:, :2]]}, "(n, 3)"),
    (lambda a: {"frames": [a["frames"][0]] * 1001}, "at most 1000"),
    (lambda a: {"garment_tris": a["garment_tris"] + 10000}, "outside"),
    (lambda a: {"values": np.zeros((2, len(a["frames"][0])))}, "one number per garment vertex"),
    (lambda a: {"fps": 0}, "fps"),
    (lambda a: {"fps": "fast"}, "fps"),
    (lambda a: {"labels": ["one"]}, "labels"),
    (lambda a: {"view": "top"}, "views"),
    (lambda a: {"size": (100, 100)}, "size"),
]


@pytest.mark.parametrize("change, words", GIF_BAD, ids=[w for _, w in GIF_BAD])
def test_gif_bad_input_raises_and_leaves_no_file(tmp_path, change, words):
    from vfit_engine.animation import write_gif

    args = _gif_args()
    args.update(change(args))
    with pytest.raises(InputError) as err:
        write_gif(tmp_path / "bad.gif", **args)
    assert words in str(err.value) and "\n" not in str(err.value)
    assert not list(tmp_path.iterdir())


def test_gif_unwritable_path_raises_input_error(tmp_path):
    from vfit_engine.animation import write_gif

    with pytest.raises(InputError, match="cannot write"):
        write_gif(tmp_path / "missing" / "d.gif", **_gif_args())


def test_bar_marks_replace_the_nearby_tick_and_draw_a_line():
    """A mark (the wearable stretch) is listed with its text, the tick it would overlap gives way, and the
    picture draws a dark line across the bar at its value (where the bar without it is coloured)."""
    bar = preview_text.bar_texts("yarn strain", "%", 0.0, 0.2, np.array([0.0, 0.2]), marks=((0.1, "10 % wearable"),))
    assert bar["marks"] == [(0.1, "10 % wearable")]
    assert [t for _, t in bar["ticks"]] == ["0 %", "5 %", "15 %", "20 %"]
    assert preview_text.bar_texts("s", "%", 0.0, 0.2, np.array([0.1]), marks=((0.5, "off"),))["marks"] == []
    verts = np.array([[0, 0, 0], [0.3, 0, 0], [0, 0.5, 0]], dtype=float)
    kw = dict(cmap="stretch", vmin=0.0, vmax=0.2, label="yarn strain", unit="%", views=("front",), size=(600, 400))
    plain = render_image(None, None, verts, [[0, 1, 2]], np.array([0.0, 0.1, 0.2]), **kw)
    marked = render_image(None, None, verts, [[0, 1, 2]], np.array([0.0, 0.1, 0.2]), marks=((0.1, "10 % wearable"),),
                          **kw)
    bar = preview_text.bar_texts("yarn strain", "%", 0.0, 0.2, np.array([0.0, 0.2]), marks=((0.1, "10 % wearable"),))
    x0, y0, x1, y1 = preview_text.layout(600, 400, 1, None, bar)["bar_box"]
    y = round(y0 + 0.5 * (y1 - y0))
    assert np.all(marked[y, x0:x1].max(axis=1) < 80)  # ink across the bar
    plain_box = preview_text.layout(600, 400, 1, None, preview_text.bar_texts(
        "yarn strain", "%", 0.0, 0.2, np.array([0.0, 0.2])))["bar_box"]
    assert np.all(np.ptp(plain[y, plain_box[0]:plain_box[2]].astype(int), axis=1) > 100)  # colour there without
