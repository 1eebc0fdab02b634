"""Text, layout and the colour bar's frame for the preview pictures (:mod:`vfit_engine.preview`).

Text is drawn with Pillow's default font (scalable with FreeType, else its small bitmap font
enlarged), so a picture needs no font file and looks the same on every machine. Everything is
sized from the picture's height, so captions stay legible from 300 x 150 to 8000 x 8000 pixels.
"""
from __future__ import annotations

import functools
import math

from PIL import Image, ImageDraw, ImageFont

from vfit_engine.errors import InputError

#: Colour of text, ticks and the bar's outline (sRGB in [0, 1]).
TEXT_RGB = (0.1, 0.1, 0.1)


def layout(width, height, n_views, title, bar, footer=False):
    """Pixel positions of everything, from the picture size and the texts to fit.

    Returns a dict: ``font_px`` (caption font), ``title_px``, ``margin``, ``top`` (first panel
    row), ``panel_w``, ``panel_h``, ``panel_x`` (left column of each panel), ``caption_y``, and
    with a bar ``bar_box`` (x0, y0, x1, y1) of its gradient; with ``footer`` a ``footer_y`` line
    under the captions (the animation's frame counter).
    """
    fs = max(11, round(0.026 * min(height, width / 2)))  # caption font: 20 px at 1500 x 750
    margin = max(4, fs // 2)
    lay = dict(font_px=fs, title_px=round(1.3 * fs), margin=margin)
    lay["top"] = margin + (line_height(lay["title_px"]) + margin if title else 0)
    caption_h = line_height(fs) + margin // 2
    footer_h = line_height(fs) + margin // 2 if footer else 0
    bar_col = bar_column_width(bar, fs) + margin if bar else 0
    area_w = width - 2 * margin - bar_col
    panel_w, panel_h = area_w // n_views, height - lay["top"] - caption_h - footer_h - margin
    if panel_w < 40 or panel_h < 40:
        raise InputError(f"a {width} x {height} picture is too small for {n_views} views")
    left = margin + (area_w - panel_w * n_views) // 2
    lay.update(panel_w=panel_w, panel_h=panel_h, caption_y=lay["top"] + panel_h + margin // 4,
               panel_x=[left + k * panel_w for k in range(n_views)])
    if footer:
        lay["footer_y"] = lay["caption_y"] + caption_h
    if bar:
        bar_h = round(0.6 * panel_h)
        x0, y0 = width - margin - bar_col + margin, lay["top"] + (panel_h - bar_h) // 2
        lay["bar_box"] = (x0, y0, x0 + fs, y0 + bar_h)
    return lay


@functools.lru_cache(maxsize=8)
def font(px):
    """(font, enlargement): Pillow's scalable default font, else its small bitmap font enlarged."""
    try:
        return ImageFont.load_default(size=px), 1
    except (TypeError, ImportError, OSError):  # Pillow < 10.1, or a build without FreeType
        return ImageFont.load_default(), max(1, round(px / 11))


def text_mask(text, px):
    """The text as a white-on-black 'L' image, one line high (same height for every text)."""
    face, k = font(px)
    if hasattr(face, "getmetrics"):
        ascent, descent = face.getmetrics()
        size = (max(1, math.ceil(face.getlength(text))), ascent + descent)
    else:
        size = (max(1, face.getbbox(text)[2]), face.getbbox("Ag")[3] + 1)
    mask = Image.new("L", size, 0)
    ImageDraw.Draw(mask).text((0, 0), text, fill=255, font=face)
    if k > 1:
        mask = mask.resize((size[0] * k, size[1] * k), Image.NEAREST)
    return mask


def line_height(px):
    return text_mask("Ag", px).size[1]


def ink():
    """TEXT_RGB as 0-255 integers (what Pillow draws with)."""
    return tuple(int(round(255 * c)) for c in TEXT_RGB)


def put_text(img, text, px, x, y, align="left", valign="top"):
    """Draw ``text`` on the PIL image with (x, y) its top-left, top-centre or left-middle point."""
    mask = text_mask(text, px)
    w, h = mask.size
    x0 = x - (w // 2 if align == "centre" else 0)
    y0 = y - (h // 2 if valign == "middle" else 0)
    img.paste(ink(), (x0, y0, x0 + w, y0 + h), mask)


def nice_step(span):
    """(step, decimals): a 1, 2, 2.5 or 5 times 10^k tick step giving about six intervals."""
    raw = span / 6.0
    mag = 10.0 ** math.floor(math.log10(raw))
    mult = next(m for m in (1.0, 2.0, 2.5, 5.0, 10.0) if m * mag >= raw * (1 - 1e-9))
    step = mult * mag
    decimals = max(0, -math.floor(math.log10(step) + 1e-9) + (1 if mult == 2.5 else 0))
    return step, decimals


def format_value(x, decimals, unit):
    s = f"{x:.{decimals}f}"
    if float(s) == 0.0:
        s = s.lstrip("-")
    return f"{s} {unit}" if unit else s


def bar_texts(label, unit, lo, hi, vals, marks=()):
    """Heading, ticks (value, text), marks (value, text), notes (data min/max) and end markers of the
    colour bar.

    ``vals`` are the values shown (any shape); with ``unit == "%"`` they, ``lo`` and ``hi`` are
    fractions and the texts are percentages. ``marks``: (value, text) lines drawn across the bar (the
    fabric's wearable stretch); a tick closer to a mark than a third of the bar's tick step gives way.
    """
    f = 100.0 if unit == "%" else 1.0
    step, dec = nice_step((hi - lo) * f)
    k0, k1 = math.ceil(lo * f / step - 1e-9), math.floor(hi * f / step + 1e-9)
    marks = [(float(v), str(t)) for v, t in marks if lo <= v <= hi]
    ticks = [(k * step / f, format_value(k * step, dec, unit)) for k in range(k0, k1 + 1)]
    return dict(
        heading=f"{label} ({unit})" if unit else label,
        ticks=[(v, t) for v, t in ticks if all(abs(v - m) * f > step / 3 for m, _ in marks)],
        marks=marks,
        notes=[f"max {format_value(vals.max() * f, dec + 1, unit)}",
               f"min {format_value(vals.min() * f, dec + 1, unit)}"],
        beyond_high=bool(vals.max() > hi), beyond_low=bool(vals.min() < lo))


def bar_column_width(bar, fs):
    labels = [*bar["ticks"], *bar.get("marks", ())]
    ticks = max(text_mask(t, fs).size[0] for _, t in labels) if labels else 0
    texts = [text_mask(t, fs).size[0] for t in [bar["heading"], *bar["notes"]]]
    return max(fs + fs // 3 + fs // 4 + ticks, *texts)


def draw_bar_frame(img, box, bar, fs, lo, hi, end_rgb):
    """Outline, ticks and labels of the bar; a triangle at an end the values go beyond.

    ``end_rgb``: the 0-255 colours of the bar's low and high ends (for the triangles).
    """
    x0, y0, x1, y1 = box
    draw, colour = ImageDraw.Draw(img), ink()
    draw.rectangle((x0 - 1, y0 - 1, x1, y1), outline=colour)
    tri = fs * 3 // 4
    if bar["beyond_high"]:
        draw.polygon([(x0 - 1, y0 - 2), (x1, y0 - 2), ((x0 + x1) / 2, y0 - 2 - tri)],
                     fill=tuple(end_rgb[1]), outline=colour)
    if bar["beyond_low"]:
        draw.polygon([(x0 - 1, y1 + 1), (x1, y1 + 1), ((x0 + x1) / 2, y1 + 1 + tri)],
                     fill=tuple(end_rgb[0]), outline=colour)
    for value, text in bar["ticks"]:
        y = round(y0 + (hi - value) / (hi - lo) * (y1 - y0))
        draw.line((x1, y, x1 + fs // 3, y), fill=colour)
        put_text(img, text, fs, x1 + fs // 3 + fs // 4, y, valign="middle")
    for value, text in bar.get("marks", ()):  # a line across the bar, out to its label
        y = round(y0 + (hi - value) / (hi - lo) * (y1 - y0))
        draw.rectangle((x0 - fs // 4, y - 1, x1 + fs // 3, y + 1), fill=colour)
        put_text(img, text, fs, x1 + fs // 3 + fs // 4, y, valign="middle")
    line = line_height(fs)
    put_text(img, bar["heading"], fs, x0, y0 - tri - fs // 2 - line)
    for k, note in enumerate(bar["notes"]):
        put_text(img, note, fs, x0, y1 + tri + fs // 2 + k * line)
