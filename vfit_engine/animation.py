"""Animated GIFs of a drape: the garment's frames on the body, drawn as the preview pictures are.

``write_gif`` draws every frame with :mod:`vfit_engine.preview`'s rasterizer, lighting, colour
maps and colour bar, through one camera framed on the body and on all the frames, so the picture
does not jump while the cloth moves. A still body is drawn once per view and each frame draws only
the garment over it; a moving body (``body_frames``, an animated fitting) is drawn in every frame. Frames share one palette and are not dithered, so what does
not move keeps its exact pixels and nothing flickers. A counter and a progress line under the
picture say where the animation is.

Importing this module imports numba and Pillow (through :mod:`vfit_engine.preview`); the CLI imports it
inside its commands, so ``vfit --help`` does not.
"""
from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from PIL import Image

from vfit_engine import preview, preview_text
from vfit_engine.errors import InputError
from vfit_engine.io.atomic import atomic_write

#: Most frames in one GIF: an animation of a drape saved every few frames has tens to hundreds;
#: Pillow holds every frame in memory until it writes the file.
MAX_FRAMES = 1000
#: Samples per pixel along each axis; 2 x 2 rather than the still's 3 x 3: 256 colours cannot show
#: the finer edge shades, and it halves the time per frame.
_SUPERSAMPLE = 2
#: Colour of the progress line's filled part and of its track (0-255).
_PROGRESS_RGB, _TRACK_RGB = (90, 90, 90), (225, 225, 225)


def write_gif(path, body_verts, body_tris, frames, garment_tris, values=None, *, fps=12,
              size=(600, 600), view="front", label="strain", unit="%", vmin=None, vmax=None,
              cmap="strain", title=None, labels=None, zoom=None, shading="gouraud", body_frames=None, marks=()):
    """Write an animated GIF (looping forever) of the garment's frames on the body.

    Parameters
    ----------
    path : str or Path
        GIF file to write (atomically: complete or not there).
    body_verts : (n, 3) float, metres, or None
        The body (the same in every frame); ``None`` (with ``body_tris`` None): garment alone.
    body_tris : (m, 3) int or None
    frames : sequence of (p, 3) float, metres, or (k, p, 3) float
        The garment's vertex positions, one array per frame, 1 to :data:`MAX_FRAMES` frames.
    garment_tris : (q, 3) int
        Garment triangles, at least one.
    values : (p,) or (k, p) float or None
        A quantity per garment vertex, the same in every frame or one row per frame; coloured
        through ``cmap`` over one range for all frames, with a colour bar (see
        :func:`vfit_engine.preview.render_views` for ``label``, ``unit``, ``vmin``, ``vmax``,
        ``cmap``, ``zoom``, ``shading`` and ``marks``). ``None``: plain cloth colour, no bar.
    body_frames : sequence of (n, 3) float, metres, or None
        The body in every frame, when it moves (``body_verts`` is then its first frame's).
    fps : float
        Frames per second, 1 to 50 (a GIF stores delays in hundredths of a second, and browsers
        slow down delays under 20 ms).
    size : (int, int)
        Width and height in pixels, from (300, 150) to (8000, 8000).
    view : str or sequence of str
        One view (``"front"``, ``"side"``, ``"left"``, ``"back"``, ``"right"``) or several side by
        side, e.g. ``("front", "side")``.
    title : str or None
        A line above the views.
    labels : sequence of str or None
        A text per frame under the views (e.g. ``"0.50 s"``); default ``"frame i of k"``.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    InputError
        A one-line message for bad input (no frames, frames of different sizes, NaN, ...) or an
        unwritable path; no file is left behind.
    """
    fps = _check_fps(fps)
    pictures = render_frames(body_verts, body_tris, frames, garment_tris, values, size=size, view=view,
                             label=label, unit=unit, vmin=vmin, vmax=vmax, cmap=cmap, title=title,
                             labels=labels, zoom=zoom, shading=shading, body_frames=body_frames, marks=marks)
    first = pictures[0]
    palette = _palette([first, pictures[-1]], pictures.bar)
    rest = (_quantize(pictures[k], palette) for k in range(1, len(pictures)))  # drawn as written
    path = Path(path)
    with atomic_write(path, "wb") as fh:
        # palette= makes Pillow write the one palette as the global colour table and no local ones
        _quantize(first, palette).save(fh, format="GIF", save_all=True, append_images=rest,
                                       palette=bytes(palette.getpalette()), duration=round(1000 / fps),
                                       loop=0, optimize=False)
    return path


def render_frames(body_verts, body_tris, frames, garment_tris, values=None, *, size=(600, 600),
                  view="front", label="strain", unit="%", vmin=None, vmax=None, cmap="strain",
                  title=None, labels=None, zoom=None, shading="gouraud", body_frames=None, marks=()):
    """The pictures of :func:`write_gif`: a sequence of (height, width, 3) uint8 sRGB arrays.

    Everything is checked at once; a picture is drawn when it is indexed (in any order), so a long
    animation is never all in memory. Arguments as in :func:`write_gif`.
    """
    positions = _check_frames(frames)
    scene = preview.check_scene(body_verts, body_tris, positions[0], garment_tris, cmap=cmap, size=size,
                                views=view, shading=shading, label=label, unit=unit)
    texts = _check_labels(labels, len(positions))
    bodies = None
    if body_frames is not None:
        if body_verts is None or len(body_frames) != len(positions):
            raise InputError(f"body_frames must give the body (body_verts, body_tris) in each of the "
                             f"{len(positions)} frames")
        bodies = [preview.check_verts(f"body_frames[{k}]", b) for k, b in enumerate(body_frames)]
        if any(b.shape != scene.meshes[0][0].shape for b in bodies):
            raise InputError("body_frames must all have the body's vertex count")
    rgb, bar, lo, hi = preview.garment_colours(values, positions[0].shape[0], cmap, vmin, vmax, label,
                                               unit, n_frames=len(positions), marks=marks)
    lay = preview_text.layout(scene.width, scene.height, len(scene.rotations), title, bar, footer=True)
    framing = preview.fit_framing([v for v, _ in scene.meshes[:-1]] + (bodies or []) + positions,
                                  scene.rotations, zoom, lay["panel_w"], lay["panel_h"])
    canvas = np.empty((scene.height, scene.width, 3))
    canvas[:] = preview.BACKGROUND_RGB
    base = preview.decorate(canvas, lay, scene.captions, title, bar, cmap, lo, hi)
    painter = _Painter(scene, framing, lay, base, shading, moving=bodies is not None)
    tris = scene.meshes[-1][1]

    def draw(k):
        colours = rgb if rgb.ndim == 2 else rgb[k]
        return painter.frame(positions[k], tris, colours, texts[k], (k + 1) / len(positions),
                             None if bodies is None else bodies[k])

    bar = None
    if "bar_box" in lay:
        x0, y0, x1, y1 = lay["bar_box"]
        bar = base[y0:y1, x0:x1]
    return _Frames(draw, len(positions), bar)


class _Frames(Sequence):
    """The animation's pictures, each drawn when indexed; ``bar``: the colour bar's pixels or None."""

    def __init__(self, draw, count, bar):
        self._draw, self._count, self.bar = draw, count, bar

    def __len__(self):
        return self._count

    def __getitem__(self, k):
        if not -self._count <= k < self._count:
            raise IndexError(k)
        return self._draw(k % self._count)


class _Painter:
    """Draws frames: the body's samples once per view, each frame's garment over a restored copy."""

    def __init__(self, scene, framing, lay, base, shading, moving=False):
        self.lay, self.base, self.shading, self.framing = lay, base, shading, framing
        ss, ph, pw = _SUPERSAMPLE, lay["panel_h"], lay["panel_w"]
        self.scene, self.moving = scene, moving
        body = [] if moving else [(v, t, c, preview.shading_normals(v, t, shading))
                                  for (v, t), c in zip(scene.meshes, scene.colours)]
        self.body = []  # per view: (image, depth) of the body alone (nothing when it moves)
        for view in range(len(scene.rotations)):
            image, depth = np.empty((ph * ss, pw * ss, 3)), np.full((ph * ss, pw * ss), -np.inf)
            image[:] = preview.BACKGROUND_RGB
            preview.draw_meshes(body, framing, view, ss, shading, image, depth)
            self.body.append((image, depth))
        self.work = [(image.copy(), depth.copy()) for image, depth in self.body]
        self.dirty = [None] * len(self.body)  # sample box the last frame's garment drew over
        self.panel = np.empty((ph, pw, 3))

    def frame(self, verts, tris, rgb, caption, progress, body_verts=None):
        """The (h, w, 3) uint8 picture of the garment at ``verts`` (coloured ``rgb``) on the body (at
        ``body_verts`` when it moves)."""
        lay, ss = self.lay, _SUPERSAMPLE
        out = self.base.copy()
        garment = [(verts, tris, rgb, preview.shading_normals(verts, tris, self.shading))]
        if self.moving:
            (_, btris), colours = self.scene.meshes[0], self.scene.colours[0]
            garment.insert(0, (body_verts, btris, colours,
                               preview.shading_normals(body_verts, btris, self.shading)))
        for view, x0 in enumerate(lay["panel_x"]):
            image, depth = self.work[view]
            if self.moving:  # everything is drawn anew
                np.copyto(image, self.body[view][0])
                np.copyto(depth, self.body[view][1])
            elif self.dirty[view] is not None:  # put the body back where the last garment was
                r0, r1, c0, c1 = self.dirty[view]
                image[r0:r1, c0:c1] = self.body[view][0][r0:r1, c0:c1]
                depth[r0:r1, c0:c1] = self.body[view][1][r0:r1, c0:c1]
            self.dirty[view] = preview.draw_meshes(garment, self.framing, view, ss, self.shading, image,
                                                   depth)
            preview.resolve_samples(image, depth, ss, self.panel)
            out[lay["top"]:lay["top"] + lay["panel_h"], x0:x0 + lay["panel_w"]] = preview.to_uint8(self.panel)
        _footer(out, lay, caption, progress)
        return out


def _footer(out, lay, caption, progress):
    """The frame's caption and a progress line under the views, drawn into ``out`` (uint8)."""
    fs, margin, y = lay["font_px"], lay["margin"], lay["footer_y"]
    mask = np.asarray(preview_text.text_mask(caption, fs), dtype=np.float64)[..., None] / 255.0
    h, w = mask.shape[:2]
    w = min(w, out.shape[1] - 2 * margin)
    region = out[y:y + h, margin:margin + w]
    alpha = mask[:region.shape[0], :w]  # as Pillow's paste with a mask: a blend towards the ink
    ink = np.asarray(preview_text.ink(), dtype=np.float64)
    region[:] = (region * (1.0 - alpha) + ink * alpha + 0.5).astype(np.uint8)
    x0 = margin + w + fs  # the line takes the rest of the row, centred on the text
    x1 = out.shape[1] - margin
    if x1 - x0 >= 10:
        yl, thick = y + h // 2, max(2, fs // 6)
        out[yl - thick // 2:yl - thick // 2 + thick, x0:x1] = _TRACK_RGB
        out[yl - thick // 2:yl - thick // 2 + thick, x0:x0 + max(1, round(progress * (x1 - x0)))] = _PROGRESS_RGB


def _palette(pictures, bar=None):
    """A 'P' image whose 256-colour palette is fitted to the pictures, shared by all frames.

    The colour bar's pixels, if given, are added to count as much as a tenth of the pictures:
    the bar is small, and without them median cut leaves it (and the garment's colours) in a
    dozen bands.
    """
    stack = np.concatenate(pictures, axis=0)
    if bar is not None and bar.size:
        reps = max(1, stack.shape[0] * stack.shape[1] // (10 * bar.shape[0] * bar.shape[1]))
        strip = np.tile(bar.reshape(-1, 3), (reps, 1))[:, None, :]
        width = stack.shape[1]
        strip = strip[:strip.shape[0] // width * width].reshape(-1, width, 3)
        stack = np.concatenate([stack, strip], axis=0)
    # every 4th pixel each way: 16 times fewer to sort (75 ms instead of 1.1 s at 600 x 600) for
    # an error a tenth larger; two k-means passes then halve the largest error of median cut
    sample = Image.fromarray(np.ascontiguousarray(stack[::4, ::4]), "RGB")
    return sample.quantize(colors=256, method=Image.Quantize.MEDIANCUT, kmeans=2, dither=Image.Dither.NONE)


def _quantize(picture, palette):
    """The picture in the shared palette; no dithering, so an unchanged pixel keeps its index."""
    return Image.fromarray(picture, "RGB").quantize(palette=palette, dither=Image.Dither.NONE)


# ---------------------------------------------------------------------------------------------
# input checks (the meshes, views and values are checked by vfit_engine.preview's)

def _check_frames(frames):
    """[(p, 3) float64] positions of every frame, all with the same vertex count."""
    try:
        count = len(frames)
    except TypeError:
        count = 0
    if not count or isinstance(frames, str):
        raise InputError("frames must be a non-empty sequence of (p, 3) garment positions")
    if count > MAX_FRAMES:
        raise InputError(f"at most {MAX_FRAMES} frames in one GIF, got {count}: pass every k-th frame")
    positions = [preview.check_verts(f"frames[{k}]", f) for k, f in enumerate(frames)]
    for k, pos in enumerate(positions):
        if pos.shape[0] != positions[0].shape[0]:
            raise InputError(f"frames[{k}] has {pos.shape[0]} vertices, frames[0] has {positions[0].shape[0]}")
    return positions


def _check_labels(labels, n_frames):
    if labels is None:
        return [f"frame {k + 1} of {n_frames}" for k in range(n_frames)]
    if isinstance(labels, str) or len(labels) != n_frames or not all(isinstance(s, str) for s in labels):
        raise InputError(f"labels must be {n_frames} strings, one per frame")
    return list(labels)


def _check_fps(fps):
    try:
        fps = float(fps)
    except (TypeError, ValueError):
        raise InputError(f"fps must be a number, got {fps!r}") from None
    if not 1.0 <= fps <= 50.0:
        raise InputError(f"fps must be from 1 to 50, got {fps:g}")
    return fps
