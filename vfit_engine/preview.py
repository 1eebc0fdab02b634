"""Preview pictures of a drape: the body and the garment from the front, the side and the back.

``render_views`` writes one PNG with the views side by side, a caption under each, and (when the
garment is coloured by a per-vertex quantity) a colour bar labelled in the quantity's unit.
The pictures are for looking at a fit: skin showing through the cloth, cloth floating off the
body, crumpled or collapsed faces show at once where a number can miss them.

Projection is orthographic with the same scale (pixels per metre) in every view, so widths can
be compared between views. Meshes are in metres, Y up, +Z the body's front, +X the body's left.
Shading is a key light from the viewer's upper left (fixed to the camera, so every view is lit
alike) plus ambient light; triangles are lit on both sides because garments are open surfaces.
Drawing is a plain z-buffer in float64 (:mod:`vfit_engine.kernels.raster`) with 2 x 2
supersampling: the garment hides the body only where it is nearer to the viewer.

Importing this module is cheap; numba and Pillow are imported when a picture is made.
"""
from __future__ import annotations

import functools
import math
from pathlib import Path

import numpy as np

from vfit_engine.errors import InputError

#: Colour of the body (sRGB in [0, 1]).
SKIN_RGB = (0.92, 0.80, 0.72)
#: Colour of the garment when no values are given: the strain map's colour at zero strain.
CLOTH_RGB = (0.25, 0.45, 0.85)
BACKGROUND_RGB = (1.0, 1.0, 1.0)
TEXT_RGB = (0.1, 0.1, 0.1)

#: Colour maps: name -> (stop positions in [0, 1], (k, 3) sRGB stops, default (vmin, vmax) or None).
#:
#: * ``strain``: yarn strain as a fraction, the same colours as the developers' render.py: dark
#:   blue at -15 %, the cloth blue at 0, yellow at +7.5 %, red at +15 % and beyond. Given vmin and
#:   vmax, the stops keep their relative places (0 at the middle only when vmin = -vmax).
#: * ``viridis``: perceptually uniform and sequential (dark purple, blue, green, yellow), for
#:   quantities that only grow such as ease (mm) or pressure (kPa). Nine stops sampled from
#:   matplotlib's viridis (CC0, van der Walt and Smith 2015), interpolated linearly in sRGB.
#:   Default range: the values' minimum and maximum. ``sequential`` is another name for it.
COLOUR_MAPS = {
    "strain": (
        (0.0, 0.5, 0.75, 1.0),
        ((0.08, 0.12, 0.45), (0.25, 0.45, 0.85), (0.95, 0.85, 0.2), (0.85, 0.1, 0.1)),
        (-0.15, 0.15),
    ),
    "viridis": (
        tuple(np.linspace(0.0, 1.0, 9)),
        ((0.267, 0.005, 0.329), (0.279, 0.175, 0.483), (0.230, 0.322, 0.546), (0.173, 0.449, 0.558),
         (0.128, 0.567, 0.551), (0.158, 0.684, 0.502), (0.369, 0.789, 0.383), (0.678, 0.864, 0.190),
         (0.993, 0.906, 0.144)),
        None,
    ),
}
COLOUR_MAPS["sequential"] = COLOUR_MAPS["viridis"]

#: View name -> (rotation world -> view space (x right, y up, z towards the viewer), caption).
VIEWS = {
    "front": (((1, 0, 0), (0, 1, 0), (0, 0, 1)), "front"),
    "left": (((0, 0, -1), (0, 1, 0), (1, 0, 0)), "side (body's left)"),
    "back": (((-1, 0, 0), (0, 1, 0), (0, 0, -1)), "back"),
    "right": (((0, 0, 1), (0, 1, 0), (-1, 0, 0)), "side (body's right)"),
}
VIEWS["side"] = VIEWS["left"]

#: Key light in view space (from the viewer's upper left, 45 degrees off the view direction:
#: a light along it would leave every surface facing the viewer equally bright) and the ambient
#: share of the shade.
_LIGHT = np.array([-0.5, 0.6, 0.7]) / np.linalg.norm([-0.5, 0.6, 0.7])
_AMBIENT = 0.25
#: Samples per pixel along each axis (antialiasing by supersampling).
_SUPERSAMPLE = 2
#: Empty border around the meshes in each view, as a fraction of the view's size.
_PAD = 0.03
#: Largest coordinate accepted, in metres (a body in millimetres or centimetres is refused).
_MAX_COORD = 100.0


def render_views(path, body_verts, body_tris, garment_verts, garment_tris, values=None, *,
                 label="strain", unit="%", vmin=None, vmax=None, cmap="strain",
                 views=("front", "side", "back"), size=(1500, 750), title=None, zoom=None,
                 shading="gouraud"):
    """Write a PNG of the body and the garment seen from several sides.

    Parameters
    ----------
    path : str or Path
        PNG file to write (atomically: complete or not there).
    body_verts : (n, 3) float, metres, or None
        Body surface; ``None`` (with ``body_tris`` None) draws the garment alone.
    body_tris : (m, 3) int or None
        Body triangles (indices into ``body_verts``).
    garment_verts : (p, 3) float, metres
    garment_tris : (q, 3) int
        Garment triangles, at least one (``MeshData.triangles()`` gives them for polygons).
    values : (p,) float or None
        A quantity per garment vertex, interpolated across the triangles and shown through
        ``cmap``, in the unit named by ``unit`` except for ``"%"``, where values are fractions
        (0.05 is drawn as 5 %). ``None``: the garment is plain cloth colour and there is no bar.
    label, unit : str
        The colour bar's heading, e.g. ``"strain"`` and ``"%"``, ``"ease"`` and ``"mm"``.
    vmin, vmax : float or None
        Values mapped to the colour map's ends (same units as ``values``); beyond them the end
        colours hold. Default: the map's own range (strain: -0.15 .. 0.15), else the values'.
    cmap : {"strain", "viridis", "sequential"}
        See :data:`COLOUR_MAPS`.
    views : sequence of {"front", "side", "left", "back", "right"}
        Left to right. ``side`` is the body's left side (the body faces the picture's left).
    size : (int, int)
        Width and height of the picture in pixels, from (300, 150) to (8000, 8000).
    title : str or None
        A line above the views.
    zoom : (float, float) or None
        Height range (ymin, ymax) in metres to frame, e.g. the torso; default the whole meshes.
        The scale is the largest at which the range's height and the meshes' width within it
        fit every view; when the width limits it (arms out), more than the range shows.
    shading : {"gouraud", "flat"}
        Per-vertex lighting interpolated across triangles, or one light level per triangle
        (shows the facets, i.e. crumpled or collapsed faces, more plainly).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    InputError
        A one-line message for bad input (shapes, NaN, indices out of range, an empty garment,
        unknown names) or an unwritable path.
    """
    from PIL import Image

    from vfit_engine.io.atomic import atomic_write

    image = render_image(body_verts, body_tris, garment_verts, garment_tris, values, label=label,
                         unit=unit, vmin=vmin, vmax=vmax, cmap=cmap, views=views, size=size,
                         title=title, zoom=zoom, shading=shading)
    path = Path(path)
    with atomic_write(path, "wb") as fh:
        # level 3: half the time of the default level 6 for 12 % more bytes
        Image.fromarray(image, "RGB").save(fh, format="PNG", compress_level=3)
    return path


def render_image(body_verts, body_tris, garment_verts, garment_tris, values=None, *,
                 label="strain", unit="%", vmin=None, vmax=None, cmap="strain",
                 views=("front", "side", "back"), size=(1500, 750), title=None, zoom=None,
                 shading="gouraud"):
    """The picture of :func:`render_views` as an (height, width, 3) uint8 sRGB array.

    Arguments as in :func:`render_views`.
    """
    from PIL import Image

    _colour_map_entry(cmap)  # a misspelt map is an error even when values is None
    width, height = _check_size(size)
    meshes = _check_meshes(body_verts, body_tris, garment_verts, garment_tris)
    rotations, captions = _check_views(views)
    if shading not in ("gouraud", "flat"):
        raise InputError(f"shading must be 'gouraud' or 'flat', not {shading!r}")
    if not isinstance(unit, str) or not isinstance(label, str):
        raise InputError("label and unit must be strings")
    bar = None
    garment_rgb = np.tile(np.asarray(CLOTH_RGB), (meshes[-1][0].shape[0], 1))
    if values is not None:
        vals = _check_values(values, meshes[-1][0].shape[0])
        lo, hi = value_range(vals, cmap, vmin, vmax)
        garment_rgb = colour_map(vals, cmap, lo, hi)
        bar = _bar_texts(label, unit, lo, hi, vals)
    meshes[-1] = (*meshes[-1][:2], garment_rgb)

    lay = _layout(width, height, len(rotations), title, bar)
    panels = _render_panels(meshes, rotations, zoom, lay["panel_w"], lay["panel_h"], shading)
    canvas = np.empty((height, width, 3))
    canvas[:] = BACKGROUND_RGB
    for x0, panel in zip(lay["panel_x"], panels):
        canvas[lay["top"]:lay["top"] + lay["panel_h"], x0:x0 + lay["panel_w"]] = panel
    if bar is not None:
        _paint_bar_gradient(canvas, lay["bar_box"], cmap, lo, hi)
    img = Image.fromarray(_to_uint8(canvas), "RGB")
    fs = lay["font_px"]
    if title:
        _put_text(img, title, lay["title_px"], width // 2, lay["margin"], "centre")
    for x0, caption in zip(lay["panel_x"], captions):
        _put_text(img, caption, fs, x0 + lay["panel_w"] // 2, lay["caption_y"], "centre")
    if bar is not None:
        _draw_bar_frame(img, lay["bar_box"], bar, fs, cmap, lo, hi)
    return np.array(img)


def colour_map(values, cmap="strain", vmin=None, vmax=None):
    """sRGB colours of values through a colour map (see :data:`COLOUR_MAPS`).

    Parameters
    ----------
    values : (n,) float
    cmap : str
        A key of :data:`COLOUR_MAPS`.
    vmin, vmax : float or None
        Values at the map's two ends (defaults as in :func:`value_range`); beyond them the end
        colours hold.

    Returns
    -------
    (n, 3) float64
        sRGB in [0, 1], interpolated linearly between the map's stops.
    """
    values = np.asarray(values, dtype=np.float64)
    positions, stops, _ = _colour_map_entry(cmap)
    lo, hi = value_range(values, cmap, vmin, vmax)
    t = (values - lo) / (hi - lo)
    stops = np.asarray(stops)
    return np.stack([np.interp(t, positions, stops[:, k]) for k in range(3)], axis=-1)


def value_range(values, cmap="strain", vmin=None, vmax=None):
    """The (vmin, vmax) a colour map is stretched over: given ones, else the map's, else the data's.

    A range of zero width (constant values) is widened by 1 % of the value (at least 0.001) either
    side, so that the values map to the middle of the map.
    """
    _, _, default = _colour_map_entry(cmap)
    values = np.asarray(values, dtype=np.float64)
    if default is None:
        default = (float(values.min()), float(values.max())) if values.size else (0.0, 1.0)
    lo = default[0] if vmin is None else float(vmin)
    hi = default[1] if vmax is None else float(vmax)
    if not (np.isfinite(lo) and np.isfinite(hi)) or lo > hi:
        raise InputError(f"colour range must be finite with vmin <= vmax, got {lo!r} .. {hi!r}")
    if lo == hi:
        half = max(abs(lo) * 0.01, 1e-3)
        lo, hi = lo - half, hi + half
    return lo, hi


def _colour_map_entry(cmap):
    if cmap not in COLOUR_MAPS:
        raise InputError(f"unknown colour map {cmap!r} (choose from {', '.join(sorted(COLOUR_MAPS))})")
    return COLOUR_MAPS[cmap]


# ---------------------------------------------------------------------------------------------
# input checks: everything is converted once here, the kernel gets contiguous float64 / int64

def _check_size(size):
    try:
        width, height = (int(s) for s in size)
    except (TypeError, ValueError):
        raise InputError(f"size must be (width, height) in pixels, got {size!r}") from None
    if not (300 <= width <= 8000 and 150 <= height <= 8000):
        raise InputError(f"size must be from 300 x 150 to 8000 x 8000 pixels, got {width} x {height}")
    return width, height


def _check_verts(name, verts):
    try:
        v = np.ascontiguousarray(verts, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be an (n, 3) array of numbers") from None
    if v.ndim != 2 or v.shape[1] != 3:
        raise InputError(f"{name} must be an (n, 3) array, got shape {v.shape}")
    bad = int(np.count_nonzero(~np.isfinite(v)))
    if bad:
        raise InputError(f"{name} has {bad} non-finite coordinates (NaN or inf)")
    if v.size and np.abs(v).max() > _MAX_COORD:
        raise InputError(f"{name} reaches {np.abs(v).max():g} from the origin: are they in metres?")
    return v


def _check_tris(name, tris, n_verts):
    t = np.asarray(tris)
    if t.ndim != 2 or t.shape[1] != 3:
        raise InputError(f"{name} must be an (m, 3) array of vertex indices, got shape {t.shape}")
    if t.size and not np.issubdtype(t.dtype, np.integer):
        raise InputError(f"{name} must hold integer vertex indices, got {t.dtype}")
    t = np.ascontiguousarray(t, dtype=np.int64)
    if t.size and (t.min() < 0 or t.max() >= n_verts):
        raise InputError(f"{name} has indices outside 0 .. {n_verts - 1}")
    return t


def _check_meshes(body_verts, body_tris, garment_verts, garment_tris):
    """[(verts, tris, rgb)] of the body (unless None) and the garment (last, rgb None)."""
    meshes = []
    if (body_verts is None) != (body_tris is None):
        raise InputError("give both body_verts and body_tris, or neither")
    if body_verts is not None:
        bv = _check_verts("body_verts", body_verts)
        bt = _check_tris("body_tris", body_tris, bv.shape[0])
        meshes.append((bv, bt, np.tile(np.asarray(SKIN_RGB), (bv.shape[0], 1))))
    gv = _check_verts("garment_verts", garment_verts)
    gt = _check_tris("garment_tris", garment_tris, gv.shape[0])
    if gt.shape[0] == 0:
        raise InputError("the garment has no triangles")
    meshes.append((gv, gt, None))
    return meshes


def _check_views(views):
    if isinstance(views, str):
        views = (views,)
    views = tuple(views)
    unknown = [v for v in views if v not in VIEWS]
    if unknown or not views:
        raise InputError(f"views must be some of {', '.join(VIEWS)}, got {views!r}")
    return [np.array(VIEWS[v][0], dtype=np.float64) for v in views], [VIEWS[v][1] for v in views]


def _check_values(values, n_verts):
    try:
        vals = np.ascontiguousarray(values, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError("values must be an array of numbers, one per garment vertex") from None
    if vals.shape != (n_verts,):
        raise InputError(f"values must have one number per garment vertex ({n_verts}), got shape {vals.shape}")
    bad = int(np.count_nonzero(~np.isfinite(vals)))
    if bad:
        raise InputError(f"values has {bad} non-finite entries (NaN or inf)")
    return vals


# ---------------------------------------------------------------------------------------------
# drawing the views

def _height_range(verts, zoom):
    """(y0, y1) in metres: the meshes' height, or the zoom range (which must hold vertices)."""
    if zoom is None:
        y0, y1 = float(verts[:, 1].min()), float(verts[:, 1].max())
        if y1 - y0 < 1e-6:  # a flat horizontal garment: give it some height
            y0, y1 = y0 - 0.05, y1 + 0.05
        return y0, y1
    try:
        y0, y1 = (float(z) for z in zoom)
    except (TypeError, ValueError):
        raise InputError(f"zoom must be (ymin, ymax) in metres, got {zoom!r}") from None
    if not (np.isfinite(y0) and np.isfinite(y1) and y0 < y1):
        raise InputError(f"zoom must be finite with ymin < ymax, got {y0!r} .. {y1!r}")
    if not np.any((verts[:, 1] >= y0) & (verts[:, 1] <= y1)):
        raise InputError(f"no vertex between heights {y0} and {y1} m (zoom)")
    return y0, y1


def _face_normals(verts, tris):
    """(m, 3) unit triangle normals (zero for degenerate triangles)."""
    n = np.cross(verts[tris[:, 1]] - verts[tris[:, 0]], verts[tris[:, 2]] - verts[tris[:, 0]])
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    return n / np.where(norm > 0, norm, 1.0)


def _render_panels(meshes, rotations, zoom, panel_w, panel_h, shading):
    """One (panel_h, panel_w, 3) float64 sRGB image per view, all at the same pixels per metre.

    Each view is centred on the meshes' horizontal extent (within the height range) and the scale
    is the largest at which every view fits its panel.
    """
    from vfit_engine.geometry import vertex_normals
    from vfit_engine.kernels.raster import downsample, rasterize

    all_v = np.concatenate([m[0] for m in meshes])
    y0, y1 = _height_range(all_v, zoom)
    framed = all_v[(all_v[:, 1] >= y0) & (all_v[:, 1] <= y1)]
    scale = panel_h * (1 - 2 * _PAD) / (y1 - y0)
    centres = []
    for rot in rotations:
        x = framed @ rot[0]
        centres.append(0.5 * (x.min() + x.max()))
        if x.max() > x.min():
            scale = min(scale, panel_w * (1 - 2 * _PAD) / (x.max() - x.min()))
    cy, ss = 0.5 * (y0 + y1), _SUPERSAMPLE
    if shading == "gouraud":
        normals = [vertex_normals(v, t) for v, t, _ in meshes]
    else:
        normals = [_face_normals(v, t) for v, t, _ in meshes]
    image = np.empty((panel_h * ss, panel_w * ss, 3))
    depth = np.empty((panel_h * ss, panel_w * ss))
    panels = []
    for rot, cx in zip(rotations, centres):
        depth[:] = -np.inf
        for (v, t, rgb), nrm in zip(meshes, normals):
            xyz = v @ rot.T
            xyz[:, 0] = (xyz[:, 0] - cx) * (scale * ss) + 0.5 * panel_w * ss
            xyz[:, 1] = (cy - xyz[:, 1]) * (scale * ss) + 0.5 * panel_h * ss
            # n_view . light = n . (rot^T light); abs: both sides of the cloth are lit
            shade = _AMBIENT + (1 - _AMBIENT) * np.abs(nrm @ (rot.T @ _LIGHT))
            if shading == "gouraud":
                colours, gain = rgb * shade[:, None], np.ones(t.shape[0])
            else:
                colours, gain = np.ascontiguousarray(rgb), shade
            rasterize(xyz, t, colours, gain, image, depth)
        panels.append(np.empty((panel_h, panel_w, 3)))
        downsample(image, depth, np.asarray(BACKGROUND_RGB, dtype=np.float64), ss, panels[-1])
    return panels


def _to_uint8(rgb):
    return (np.clip(rgb, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)


# ---------------------------------------------------------------------------------------------
# layout, text and the colour bar

def _layout(width, height, n_views, title, bar):
    """Pixel positions of everything, from the picture size and the texts to fit."""
    fs = max(11, round(0.026 * min(height, width / 2)))  # caption font: 20 px at 1500 x 750
    margin = max(4, fs // 2)
    lay = dict(font_px=fs, title_px=round(1.3 * fs), margin=margin)
    lay["top"] = margin + (_line_height(lay["title_px"]) + margin if title else 0)
    caption_h = _line_height(fs) + margin // 2
    bar_col = _bar_column_width(bar, fs) + margin if bar else 0
    area_w = width - 2 * margin - bar_col
    panel_w, panel_h = area_w // n_views, height - lay["top"] - caption_h - margin
    if panel_w < 40 or panel_h < 40:
        raise InputError(f"a {width} x {height} picture is too small for {n_views} views")
    left = margin + (area_w - panel_w * n_views) // 2
    lay.update(panel_w=panel_w, panel_h=panel_h, caption_y=lay["top"] + panel_h + margin // 4,
               panel_x=[left + k * panel_w for k in range(n_views)])
    if bar:
        bar_h = round(0.6 * panel_h)
        x0, y0 = width - margin - bar_col + margin, lay["top"] + (panel_h - bar_h) // 2
        lay["bar_box"] = (x0, y0, x0 + fs, y0 + bar_h)
    return lay


@functools.lru_cache(maxsize=8)
def _font(px):
    """(font, enlargement): Pillow's scalable default font, else its small bitmap font enlarged."""
    from PIL import ImageFont

    try:
        return ImageFont.load_default(size=px), 1
    except (TypeError, ImportError, OSError):  # Pillow < 10.1, or a build without FreeType
        return ImageFont.load_default(), max(1, round(px / 11))


def _text_mask(text, px):
    """The text as a white-on-black 'L' image, one line high (same height for every text)."""
    from PIL import Image, ImageDraw

    font, k = _font(px)
    if hasattr(font, "getmetrics"):
        ascent, descent = font.getmetrics()
        size = (max(1, math.ceil(font.getlength(text))), ascent + descent)
    else:
        size = (max(1, font.getbbox(text)[2]), font.getbbox("Ag")[3] + 1)
    mask = Image.new("L", size, 0)
    ImageDraw.Draw(mask).text((0, 0), text, fill=255, font=font)
    if k > 1:
        mask = mask.resize((size[0] * k, size[1] * k), Image.NEAREST)
    return mask


def _line_height(px):
    return _text_mask("Ag", px).size[1]


def _put_text(img, text, px, x, y, align="left", valign="top"):
    """Draw ``text`` on the PIL image with (x, y) its top-left, top-centre or left-middle point."""
    mask = _text_mask(text, px)
    w, h = mask.size
    x0 = x - (w // 2 if align == "centre" else 0)
    y0 = y - (h // 2 if valign == "middle" else 0)
    img.paste(tuple(int(round(255 * c)) for c in TEXT_RGB), (x0, y0, x0 + w, y0 + h), mask)


def _nice_step(span):
    """(step, decimals): a 1, 2, 2.5 or 5 times 10^k tick step giving about six intervals."""
    raw = span / 6.0
    mag = 10.0 ** math.floor(math.log10(raw))
    mult = next(m for m in (1.0, 2.0, 2.5, 5.0, 10.0) if m * mag >= raw * (1 - 1e-9))
    step = mult * mag
    decimals = max(0, -math.floor(math.log10(step) + 1e-9) + (1 if mult == 2.5 else 0))
    return step, decimals


def _format(x, decimals, unit):
    s = f"{x:.{decimals}f}"
    if float(s) == 0.0:
        s = s.lstrip("-")
    return f"{s} {unit}" if unit else s


def _bar_texts(label, unit, lo, hi, vals):
    """Heading, ticks (value, text), notes (data min/max) and end markers of the colour bar."""
    f = 100.0 if unit == "%" else 1.0  # "%": the values are fractions
    step, dec = _nice_step((hi - lo) * f)
    k0, k1 = math.ceil(lo * f / step - 1e-9), math.floor(hi * f / step + 1e-9)
    return dict(
        heading=f"{label} ({unit})" if unit else label,
        ticks=[(k * step / f, _format(k * step, dec, unit)) for k in range(k0, k1 + 1)],
        notes=[f"max {_format(vals.max() * f, dec + 1, unit)}",
               f"min {_format(vals.min() * f, dec + 1, unit)}"],
        beyond_high=bool(vals.max() > hi), beyond_low=bool(vals.min() < lo))


def _bar_column_width(bar, fs):
    ticks = max(_text_mask(t, fs).size[0] for _, t in bar["ticks"]) if bar["ticks"] else 0
    texts = [_text_mask(t, fs).size[0] for t in [bar["heading"], *bar["notes"]]]
    return max(fs + fs // 3 + fs // 4 + ticks, *texts)


def _paint_bar_gradient(canvas, box, cmap, lo, hi):
    x0, y0, x1, y1 = box
    rows = hi - (np.arange(y1 - y0) + 0.5) / (y1 - y0) * (hi - lo)
    canvas[y0:y1, x0:x1] = colour_map(rows, cmap, lo, hi)[:, None, :]


def _draw_bar_frame(img, box, bar, fs, cmap, lo, hi):
    """Outline, ticks and labels of the bar; a triangle at an end the values go beyond."""
    from PIL import ImageDraw

    x0, y0, x1, y1 = box
    draw, ink = ImageDraw.Draw(img), tuple(int(round(255 * c)) for c in TEXT_RGB)
    draw.rectangle((x0 - 1, y0 - 1, x1, y1), outline=ink)
    tri = fs * 3 // 4
    ends = _to_uint8(colour_map(np.array([lo, hi]), cmap, lo, hi))
    if bar["beyond_high"]:
        draw.polygon([(x0 - 1, y0 - 2), (x1, y0 - 2), ((x0 + x1) / 2, y0 - 2 - tri)],
                     fill=tuple(ends[1]), outline=ink)
    if bar["beyond_low"]:
        draw.polygon([(x0 - 1, y1 + 1), (x1, y1 + 1), ((x0 + x1) / 2, y1 + 1 + tri)],
                     fill=tuple(ends[0]), outline=ink)
    for value, text in bar["ticks"]:
        y = round(y0 + (hi - value) / (hi - lo) * (y1 - y0))
        draw.line((x1, y, x1 + fs // 3, y), fill=ink)
        _put_text(img, text, fs, x1 + fs // 3 + fs // 4, y, valign="middle")
    line = _line_height(fs)
    _put_text(img, bar["heading"], fs, x0, y0 - tri - fs // 2 - line)
    for k, note in enumerate(bar["notes"]):
        _put_text(img, note, fs, x0, y1 + tri + fs // 2 + k * line)
