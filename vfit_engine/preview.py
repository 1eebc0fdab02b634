"""Preview pictures of a drape: the body and the garment from the front, the side and the back.

``render_views`` writes one PNG with the views side by side, a caption under each, and (when the
garment is coloured by a per-vertex quantity) a colour bar labelled in the quantity's unit.
The pictures are for looking at a fit: skin showing through the cloth, cloth floating off the
body, crumpled or collapsed faces show at once where a number can miss them.

Projection is orthographic with the same scale (pixels per metre) in every view, so widths can
be compared between views. Meshes are in metres, Y up, +Z the body's front, +X the body's left.
Shading is a key light from the viewer's upper left (fixed to the camera, so every view is lit
alike) plus ambient light; triangles are lit on both sides because garments are open surfaces.
Drawing is a plain z-buffer in float64 (:mod:`vfit_engine.kernels.raster`) with 3 x 3
supersampling: the garment hides the body only where it is nearer to the viewer. Text, layout
and the colour bar's frame are in :mod:`vfit_engine.preview_text`; :mod:`vfit_engine.animation`
draws frames of a drape with the same pieces, this module's drawing API: :func:`check_scene`,
:func:`check_verts`, :func:`garment_colours` (the checks), :func:`fit_framing`, :func:`shading_normals`,
:func:`draw_meshes`, :func:`resolve_samples`, :func:`to_uint8` and :func:`decorate` (the drawing).

Importing this module imports numba (the rasterizer's kernels) and Pillow; the CLI imports it inside its
commands, so ``vfit --help`` does not.
"""
from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

import numpy as np
from PIL import Image

from vfit_engine import preview_text as text
from vfit_engine.errors import InputError
from vfit_engine.geometry import vertex_normals
from vfit_engine.io.atomic import atomic_write
from vfit_engine.kernels.raster import downsample, rasterize
from vfit_engine.preview_text import TEXT_RGB  # noqa: F401  (part of the colour scheme's names)

#: Colour of the body (sRGB in [0, 1]).
SKIN_RGB = (0.92, 0.80, 0.72)
#: Colour of the garment when no values are given: the strain map's colour at zero strain.
CLOTH_RGB = (0.25, 0.45, 0.85)
BACKGROUND_RGB = (1.0, 1.0, 1.0)

#: Colour maps: name -> (stop positions in [0, 1], (k, 3) sRGB stops, default (vmin, vmax) or None).
#:
#: * ``strain``: yarn strain as a fraction, the same colours as the developers' render.py: dark
#:   blue at -15 %, the cloth blue at 0, yellow at +7.5 %, red at +15 % and beyond. Given vmin and
#:   vmax, the stops keep their relative places (0 at the middle only when vmin = -vmax).
#: * ``stretch``: yarn strain as a fraction on a sequential scale from 0 (the fit preview's): the cloth
#:   blue at 0 and below (cloth shorter than given is gathered or buckled, free of tension: the solver
#:   leaves compression free, so it is not drawn as a load), green, yellow at the middle, orange, red
#:   at the end. The fit preview puts the middle at the fabric's wearable stretch (range 0 .. twice it,
#:   marked on the bar): yellow is "as far as the fabric gives", red "twice that". Default range 0 .. 20 %.
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
    "stretch": (
        (0.0, 0.25, 0.5, 0.75, 1.0),
        ((0.25, 0.45, 0.85), (0.30, 0.68, 0.62), (0.95, 0.85, 0.2), (0.95, 0.52, 0.12), (0.85, 0.1, 0.1)),
        (0.0, 0.20),
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
#: Samples per pixel along each axis (antialiasing by supersampling): 3 x 3 gives silhouettes ten
#: coverage levels instead of five at 2 x 2, for about 80 ms more on 1500 x 750 (BENCHMARKS.md).
_SUPERSAMPLE = 3
#: Empty border around the meshes in each view, as a fraction of the view's size.
_PAD = 0.03
#: Largest coordinate accepted, in metres (a body in millimetres or centimetres is refused).
_MAX_COORD = 100.0


def render_views(path, body_verts, body_tris, garment_verts, garment_tris, values=None, *,
                 label="strain", unit="%", vmin=None, vmax=None, cmap="strain",
                 views=("front", "side", "back"), size=(1500, 750), title=None, zoom=None,
                 shading="gouraud", marks=()):
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
    cmap : {"strain", "stretch", "viridis", "sequential"}
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
    marks : sequence of (value, text)
        Lines across the colour bar at these values (in the values' units), labelled, e.g. the
        fabric's wearable stretch.

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
    image = render_image(body_verts, body_tris, garment_verts, garment_tris, values, label=label,
                         unit=unit, vmin=vmin, vmax=vmax, cmap=cmap, views=views, size=size,
                         title=title, zoom=zoom, shading=shading, marks=marks)
    path = Path(path)
    with atomic_write(path, "wb") as fh:
        # level 3: half the time of the default level 6 for 12 % more bytes
        Image.fromarray(image, "RGB").save(fh, format="PNG", compress_level=3)
    return path


def render_image(body_verts, body_tris, garment_verts, garment_tris, values=None, *,
                 label="strain", unit="%", vmin=None, vmax=None, cmap="strain",
                 views=("front", "side", "back"), size=(1500, 750), title=None, zoom=None,
                 shading="gouraud", marks=()):
    """The picture of :func:`render_views` as an (height, width, 3) uint8 sRGB array.

    Arguments as in :func:`render_views`.
    """
    scene = check_scene(body_verts, body_tris, garment_verts, garment_tris, cmap=cmap, size=size,
                        views=views, shading=shading, label=label, unit=unit)
    gv = scene.meshes[-1][0]
    rgb, bar, lo, hi = garment_colours(values, gv.shape[0], cmap, vmin, vmax, label, unit, marks=marks)
    lay = text.layout(scene.width, scene.height, len(scene.rotations), title, bar)
    meshes = [(v, t, c, shading_normals(v, t, shading))
              for (v, t), c in zip(scene.meshes, [*scene.colours, rgb])]
    framing = fit_framing([v for v, _ in scene.meshes], scene.rotations, zoom, lay["panel_w"], lay["panel_h"])
    canvas = np.empty((scene.height, scene.width, 3))
    canvas[:] = BACKGROUND_RGB
    ss = _SUPERSAMPLE
    image = np.empty((lay["panel_h"] * ss, lay["panel_w"] * ss, 3))
    depth = np.empty((lay["panel_h"] * ss, lay["panel_w"] * ss))
    panel = np.empty((lay["panel_h"], lay["panel_w"], 3))
    for view, x0 in enumerate(lay["panel_x"]):
        depth[:] = -np.inf
        draw_meshes(meshes, framing, view, ss, shading, image, depth)
        resolve_samples(image, depth, ss, panel)
        canvas[lay["top"]:lay["top"] + lay["panel_h"], x0:x0 + lay["panel_w"]] = panel
    return decorate(canvas, lay, scene.captions, title, bar, cmap, lo, hi)


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


def check_verts(name, verts):
    """(n, 3) float64 contiguous vertices in metres, or an InputError naming ``name``."""
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


class Scene(NamedTuple):
    """What the checks hand on: picture size, meshes and views, all converted once."""

    width: int
    height: int
    meshes: list  # [(verts (n, 3) float64, tris (m, 3) int64)]: the body (if any), the garment last
    colours: list  # [(n, 3) float64 sRGB] of the meshes before the garment (the skin)
    rotations: list  # (3, 3) float64 world -> view per view
    captions: list


def check_scene(body_verts, body_tris, garment_verts, garment_tris, *, cmap, size, views, shading, label,
                unit):
    """Check and convert everything but the values (see :func:`render_views` for the arguments)."""
    _colour_map_entry(cmap)  # a misspelt map is an error even when values is None
    width, height = _check_size(size)
    meshes = _check_meshes(body_verts, body_tris, garment_verts, garment_tris)
    rotations, captions = _check_views(views)
    if shading not in ("gouraud", "flat"):
        raise InputError(f"shading must be 'gouraud' or 'flat', not {shading!r}")
    if not isinstance(unit, str) or not isinstance(label, str):
        raise InputError("label and unit must be strings")
    skin = [np.tile(np.asarray(SKIN_RGB), (v.shape[0], 1)) for v, _ in meshes[:-1]]
    return Scene(width, height, meshes, skin, rotations, captions)


def garment_colours(values, n_verts, cmap, vmin, vmax, label, unit, n_frames=None, marks=()):
    """(rgb (n_verts, 3) or (n_frames, n_verts, 3), bar texts or None, lo, hi) of the garment.

    ``values``: None (plain cloth colour, no bar), (n_verts,) or, for an animation of
    ``n_frames``, (n_frames, n_verts) values whose common range sets the colours of every frame.
    ``marks``: (value, text) lines across the bar (:func:`render_views`).
    """
    if values is None:
        return np.tile(np.asarray(CLOTH_RGB), (n_verts, 1)), None, 0.0, 1.0
    vals = _check_values(values, n_verts, n_frames)
    lo, hi = value_range(vals.ravel(), cmap, vmin, vmax)
    rgb = colour_map(vals.ravel(), cmap, lo, hi).reshape(*vals.shape, 3)
    return rgb, text.bar_texts(label, unit, lo, hi, vals, marks), lo, hi


def _check_meshes(body_verts, body_tris, garment_verts, garment_tris):
    """[(verts, tris)] of the body (unless None) and the garment (last)."""
    meshes = []
    if (body_verts is None) != (body_tris is None):
        raise InputError("give both body_verts and body_tris, or neither")
    if body_verts is not None:
        bv = check_verts("body_verts", body_verts)
        meshes.append((bv, _check_tris("body_tris", body_tris, bv.shape[0])))
    gv = check_verts("garment_verts", garment_verts)
    gt = _check_tris("garment_tris", garment_tris, gv.shape[0])
    if gt.shape[0] == 0:
        raise InputError("the garment has no triangles")
    meshes.append((gv, gt))
    return meshes


def _check_views(views):
    if isinstance(views, str):
        views = (views,)
    views = tuple(views)
    unknown = [v for v in views if v not in VIEWS]
    if unknown or not views:
        raise InputError(f"views must be some of {', '.join(VIEWS)}, got {views!r}")
    return [np.array(VIEWS[v][0], dtype=np.float64) for v in views], [VIEWS[v][1] for v in views]


def _check_values(values, n_verts, n_frames=None):
    """(n_verts,) float64 values; with ``n_frames`` also (n_frames, n_verts), one row per frame."""
    try:
        vals = np.ascontiguousarray(values, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError("values must be an array of numbers, one per garment vertex") from None
    if vals.shape != (n_verts,) and (n_frames is None or vals.shape != (n_frames, n_verts)):
        rows = "" if n_frames is None else f" (or a row of them per frame, {n_frames})"
        raise InputError(f"values must have one number per garment vertex ({n_verts}){rows}, got shape "
                         f"{vals.shape}")
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


class Framing(NamedTuple):
    """Orthographic cameras: ``x_pix = (x_view - centres[k]) * scale + panel_w / 2`` and
    ``y_pix = (cy - y) * scale + panel_h / 2``, in pixels of the final picture."""

    scale: float  # pixels per metre, the same in every view
    centres: list  # horizontal view coordinate (m) at each panel's middle
    cy: float  # height (m) at the panels' middle
    rotations: list
    panel_w: int
    panel_h: int


def fit_framing(verts_list, rotations, zoom, panel_w, panel_h):
    """The cameras that fit every vertex of ``verts_list`` (within the height range) in every panel.

    Each view is centred on the meshes' horizontal extent and the scale is the largest at which
    every view fits its panel; an animation passes every frame so that the picture does not jump.
    """
    all_v = np.concatenate(verts_list)
    y0, y1 = _height_range(all_v, zoom)
    framed = all_v[(all_v[:, 1] >= y0) & (all_v[:, 1] <= y1)]
    scale = panel_h * (1 - 2 * _PAD) / (y1 - y0)
    centres = []
    for rot in rotations:
        x = framed @ rot[0]
        centres.append(0.5 * (x.min() + x.max()))
        if x.max() > x.min():
            scale = min(scale, panel_w * (1 - 2 * _PAD) / (x.max() - x.min()))
    return Framing(scale, centres, 0.5 * (y0 + y1), rotations, panel_w, panel_h)


def shading_normals(verts, tris, shading):
    """Vertex normals (gouraud) or face normals (flat) of a mesh."""
    if shading == "gouraud":
        return vertex_normals(verts, tris)
    return _face_normals(verts, tris)


def draw_meshes(meshes, framing, view, ss, shading, image, depth):
    """Rasterize meshes [(verts, tris, rgb, normals)] as seen in ``view`` into the sample buffers.

    ``image`` (panel_h ss, panel_w ss, 3) and ``depth`` (panel_h ss, panel_w ss) are drawn over,
    not cleared: a still clears ``depth`` once per view, an animation draws the body once and each
    frame's garment over it. Returns the rows and columns ``(r0, r1, c0, c1)`` (end exclusive,
    within the buffers) the meshes' vertices span: all that the drawing can have changed.
    """
    rot, f = framing.rotations[view], framing.scale * ss
    light = rot.T @ _LIGHT  # n_view . light = n . (rot^T light)
    h, w = depth.shape
    box = [h, 0, w, 0]
    for v, t, rgb, nrm in meshes:
        xyz = v @ rot.T
        xyz[:, 0] = (xyz[:, 0] - framing.centres[view]) * f + 0.5 * framing.panel_w * ss
        xyz[:, 1] = (framing.cy - xyz[:, 1]) * f + 0.5 * framing.panel_h * ss
        shade = _AMBIENT + (1 - _AMBIENT) * np.abs(nrm @ light)  # abs: both sides of the cloth are lit
        if shading == "gouraud":
            colours, gain = rgb * shade[:, None], np.ones(t.shape[0])
        else:
            colours, gain = np.ascontiguousarray(rgb), shade
        rasterize(xyz, t, colours, gain, image, depth)
        lo, hi = np.floor(xyz[:, :2].min(axis=0)), np.ceil(xyz[:, :2].max(axis=0)) + 1
        box = [min(box[0], max(0, int(lo[1]))), max(box[1], min(h, int(hi[1]))),
               min(box[2], max(0, int(lo[0]))), max(box[3], min(w, int(hi[0])))]
    return tuple(box)


def resolve_samples(image, depth, ss, panel_out):
    """Average the samples into the (panel_h, panel_w, 3) panel; empty samples are background."""
    downsample(image, depth, np.asarray(BACKGROUND_RGB, dtype=np.float64), ss, panel_out)


def to_uint8(rgb):
    """sRGB floats in [0, 1] (clipped) as uint8 0-255, rounded to nearest."""
    return (np.clip(rgb, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)


def decorate(canvas, lay, captions, title, bar, cmap, lo, hi):
    """The (h, w, 3) uint8 picture: the float canvas with the bar's gradient, texts and the bar's frame."""
    if bar is not None:
        x0, y0, x1, y1 = lay["bar_box"]
        rows = hi - (np.arange(y1 - y0) + 0.5) / (y1 - y0) * (hi - lo)
        canvas[y0:y1, x0:x1] = colour_map(rows, cmap, lo, hi)[:, None, :]
    img = Image.fromarray(to_uint8(canvas), "RGB")
    fs = lay["font_px"]
    if title:
        text.put_text(img, title, lay["title_px"], canvas.shape[1] // 2, lay["margin"], "centre")
    for x0, caption in zip(lay["panel_x"], captions):
        text.put_text(img, caption, fs, x0 + lay["panel_w"] // 2, lay["caption_y"], "centre")
    if bar is not None:
        ends = to_uint8(colour_map(np.array([lo, hi]), cmap, lo, hi))
        text.draw_bar_frame(img, lay["bar_box"], bar, fs, lo, hi, ends)
    return np.array(img)
