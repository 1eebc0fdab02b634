"""The flat pattern as a picture: every panel laid out side by side, its seams, grain lines and edge lengths.

This is what ``vfit pattern show`` writes: a pattern maker checks at a glance that the file was read as meant
(which edges are sewn to which, the grain, the lengths). Panels are placed by a shelf packing (tallest first,
left to right, a new row when the row is full), in their own frame, y up, never rotated: the picture shows
the file's pieces as they are. Drawn with Pillow only.
"""

from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from vfit_engine.errors import InputError
from vfit_engine.io.atomic import atomic_write
from vfit_engine.preview_text import text_mask

from . import curves

#: Distinct colours for seams (sRGB 0-255); seam k is drawn in colour k modulo their count.
SEAM_RGB = ((31, 119, 180), (214, 39, 40), (44, 160, 44), (148, 103, 189), (255, 127, 14), (23, 190, 207),
            (140, 86, 75), (227, 119, 194), (150, 150, 20), (0, 0, 128), (128, 0, 0), (0, 128, 128))
EDGE_RGB = (70, 70, 70)  # an edge sewn to nothing (a hem, an opening)
FILL_RGB = (246, 242, 232)
GRAIN_RGB = (110, 110, 110)
INK_RGB = (25, 25, 25)
GAP_M = 0.06  # between panels, room for the lengths written inside their edges
SCALE_BAR_M = 0.10


def layout(sizes, row_width):
    """Shelf packing: lower-left corners (n, 2) of boxes ``sizes`` (n, 2), tallest first, rows of ``row_width``
    (a box wider than a row gets a row to itself); rows go down from y = 0. Returns (corners, total (w, h))."""
    sizes = np.asarray(sizes, float)
    order = np.argsort(-sizes[:, 1], kind="stable")
    corners = np.zeros_like(sizes)
    x = y_top = row_h = width = 0.0
    for i in order:
        w, h = sizes[i]
        if x > 0 and x + w > row_width:
            y_top, x, row_h = y_top + row_h + GAP_M, 0.0, 0.0
        row_h = max(row_h, h)
        corners[i] = (x, -y_top - h)  # the boxes' tops line up along the row's top
        x += w + GAP_M
        width = max(width, x - GAP_M)
    return corners, (width, y_top + row_h)


def _best_layout(sizes, aspect=1.4):
    """The shelf packing whose row width gives the smallest picture of ``aspect`` (width / height) holding it."""
    widest, total = sizes[:, 0].max(), (sizes[:, 0] + GAP_M).sum()
    best = None
    for row in np.linspace(widest, max(total, widest), 32):
        corners, (w, h) = layout(sizes, row)
        score = max(w, aspect * h)
        if best is None or score < best[0] - 1e-12:
            best = (score, corners, (w, h))
    return best[1], best[2]


def draw_pattern(pattern, png_path, width_px=1600):
    """Draw the flat panels of ``pattern`` into a PNG.

    Each outline is drawn edge by edge: the two edges of seam k in the same colour, each marked with k;
    every edge's length in cm inside it; grain lines as double arrows; panel names; a 10 cm scale bar.

    Parameters
    ----------
    pattern : model.Pattern
    png_path : str or Path
    width_px : int
        The picture's width; its height follows from the layout.

    Returns
    -------
    dict
        ``size`` (w, h) in pixels and ``boxes``: {panel name: (x0, y0, x1, y1)} pixel box of each panel.
    """
    if not pattern.panels:
        raise InputError(f"{pattern.source}: no panels to draw")
    if width_px < 300:
        raise InputError(f"a picture {width_px} px wide is too small for a pattern (300 at least)")
    names = list(pattern.panels)
    outlines = {n: _outline(pattern.panels[n]) for n in names}
    lo = {n: o.min(axis=0) for n, o in outlines.items()}
    sizes = np.array([np.ptp(outlines[n], axis=0) for n in names])
    corners, (total_w, total_h) = _best_layout(sizes)
    fs = max(11, round(width_px / 90))
    margin = 2 * fs
    px_m = (width_px - 2 * margin) / total_w
    top = margin + 2 * fs
    height = int(top + total_h * px_m + margin + 3 * fs)
    img = Image.new("RGB", (width_px, height), (255, 255, 255))
    draw = ImageDraw.Draw(img)

    def to_px(name, xy, k):
        xy = np.asarray(xy, float) - lo[name] + corners[k]
        return np.column_stack([margin + xy[:, 0] * px_m, top - xy[:, 1] * px_m])

    seams_of = _seams_of(pattern)
    boxes = {}
    for k, name in enumerate(names):
        panel, poly = pattern.panels[name], to_px(name, outlines[name], k)
        draw.polygon([tuple(p) for p in poly], fill=FILL_RGB)
        boxes[name] = tuple(int(v) for v in (*poly.min(axis=0), *poly.max(axis=0)))
        inward = 1.0 if _signed_area(outlines[name]) > 0 else -1.0  # y flips in the picture
        for i, e in enumerate(panel.edges):
            pts = to_px(name, curves.chords(e.kind, panel.edge_ends(i), e.controls, 0.5 / px_m), k)
            marks = seams_of.get((name, i), [])
            rgb = SEAM_RGB[marks[0] % len(SEAM_RGB)] if marks else EDGE_RGB
            draw.line([tuple(p) for p in pts], fill=rgb, width=max(2, fs // 6) if marks else max(1, fs // 9))
            _edge_labels(img, draw, pts, inward, f"{panel.edge_length(i) * 100:.1f}", marks, rgb, fs)
        _grain(draw, to_px(name, outlines[name], k), panel.grain, fs)
        centre = 0.5 * (poly.min(axis=0) + poly.max(axis=0))
        _text(img, name, fs, centre[0], centre[1] - 1.2 * fs, INK_RGB, background=FILL_RGB)
    n_seams = len(pattern.stitches)
    _text(img, f"{Path(str(pattern.source)).name}: {len(names)} panels, {n_seams} seams; lengths in cm, seam numbers in circles",
          fs, margin, margin // 2, INK_RGB, anchor="lt")
    y = height - margin - fs
    bar = SCALE_BAR_M * px_m
    draw.rectangle((margin, y, margin + bar, y + fs // 3), fill=INK_RGB)
    _text(img, "10 cm", fs, margin + bar + fs // 2, y + fs // 6, INK_RGB, anchor="lm")
    with atomic_write(png_path, "wb") as f:
        img.save(f, format="PNG")
    return dict(size=img.size, boxes=boxes)


def _outline(panel):
    return np.concatenate([curves.chords(e.kind, panel.edge_ends(i), e.controls, 1e-3)[:-1]
                           for i, e in enumerate(panel.edges)])


def _signed_area(points):
    x, y = points[:, 0], points[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def _seams_of(pattern):
    """{(panel, edge): [seam numbers from 1]} of every stitched edge."""
    found = {}
    for k, st in enumerate(pattern.stitches, start=1):
        for ref in (st.a, st.b):
            found.setdefault((ref.panel, ref.edge), []).append(k)
    return found


def _edge_labels(img, draw, pts, inward, length, marks, rgb, fs):
    """The edge's length (and its seam numbers in a disc) at its middle, inside the panel."""
    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    if cum[-1] < 1.0:
        return
    k = min(int(np.searchsorted(cum, 0.5 * cum[-1])), len(seg)) - 1
    k = max(k, 0)
    t = (0.5 * cum[-1] - cum[k]) / max(seg[k], 1e-9)
    mid = pts[k] + t * (pts[k + 1] - pts[k])
    d = (pts[k + 1] - pts[k]) / max(seg[k], 1e-9)
    normal = -inward * np.array([-d[1], d[0]])  # into the panel (picture y runs down)
    small = max(10, round(0.8 * fs))
    if marks:
        tag = text_mask(",".join(map(str, marks)), small)
        r = 0.5 * max(tag.size[0], tag.size[1]) + 0.2 * small
        c = mid + normal * 0.9 * r
        draw.ellipse((c[0] - r, c[1] - r, c[0] + r, c[1] + r), fill=rgb)
        _text(img, ",".join(map(str, marks)), small, c[0], c[1], (255, 255, 255), anchor="mm")
        mid = c + normal * r
    w, h = text_mask(length, small).size
    # far enough along the normal that the text's box clears the edge, whichever way the edge runs
    place = mid + normal * (0.5 * (abs(normal[0]) * w + abs(normal[1]) * h) + 0.25 * small)
    _text(img, length, small, place[0], place[1], rgb if marks else EDGE_RGB, anchor="mm")


def _grain(draw, poly, grain, fs):
    """The grain line: a double arrow through the panel's middle along the grain, over half its extent."""
    g = np.asarray(grain, float)
    g = np.array([g[0], -g[1]]) / max(np.linalg.norm(g), 1e-12)  # picture y runs down
    centre = 0.5 * (poly.min(axis=0) + poly.max(axis=0))
    half = 0.25 * np.ptp(poly @ g)
    a, b = centre - half * g, centre + half * g
    draw.line((tuple(a), tuple(b)), fill=GRAIN_RGB, width=max(1, fs // 8))
    side = np.array([-g[1], g[0]])
    for tip, back in ((b, -g), (a, g)):
        base = tip + back * 0.8 * fs
        draw.polygon([tuple(tip), tuple(base + side * 0.35 * fs), tuple(base - side * 0.35 * fs)], fill=GRAIN_RGB)


def _text(img, text, px, x, y, rgb, anchor="mm", background=None):
    """Draw ``text`` in colour ``rgb`` with its anchor at (x, y): "mm" its middle, "lt" its top-left, "lm" its
    left middle; on a box of ``background`` when given."""
    mask = text_mask(text, px)
    w, h = mask.size
    x0 = int(round(x - (w / 2 if anchor[0] == "m" else 0)))
    y0 = int(round(y - (h / 2 if anchor[1] == "m" else 0)))
    if background is not None:
        ImageDraw.Draw(img).rectangle((x0 - 2, y0 - 1, x0 + w + 2, y0 + h + 1), fill=background)
    img.paste(rgb, (x0, y0, x0 + w, y0 + h), mask)
