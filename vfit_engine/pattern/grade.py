"""Grade a sewing pattern from the body it was made for to another body: a size run made from one pattern.

The rule (:data:`RULE`; ``vfit size`` prints it), on the flat pattern's curves before anything is meshed:

1. **Girths of the trunk.** At each girth level of the body -- bust (men: chest), waist, hips -- the panels
   that go round the trunk (every panel but sleeves, cuffs, collars and waistbands) and cross that level are
   found, and their widths there summed: the garment's girth at the level, ``W``. Every one of those panels'
   widths is scaled by ``s = 1 + d / W``, ``d`` the change of the body's girth there, so the growth is spread
   over the panels in proportion to their width and the garment's girth grows by exactly the body's change.
   A level no panel crosses is left out.
2. **Between the levels**, the scale is linear in height (the panel's height on the body the pattern was made
   for: from its frame or its placement); above the highest level and below the lowest crossed it stays that
   level's. A panel is scaled across its own vertical axis (the direction its height grows along), about its
   centre line when it is a front or back panel crossing the body's centre line (a half panel grows towards
   its side seam), else about its middle. Collars and waistbands take the scale at their height: they go
   round with the panels they are sewn to.
3. **Sleeves** (and cuffs): each arm's panels -- the sleeve panels sewn to each other -- are scaled across the
   arm by ``1 + d_arm / W_arm``, the upper arm's change over the sleeve's girth just below its cap, and each
   sleeve's cap height (the part above the cap's lowest point) by the one factor that keeps the caps as much
   longer (or shorter) than their graded armholes as they were: the cap still goes into its armhole with the
   ease it had.
4. **Lengths are as made**: nothing is graded in height (a letter size is a girth size; the length of a
   pattern is its own).

Every graded pattern is validated (:func:`vfit_engine.pattern.validate.validate`) before it is used. Real grade
rules grow the neck and the shoulders less than the bust; here everything above the bust grows with it.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from vfit_engine.body.measure import Measurer
from vfit_engine.body.resolve import Body, default_body, resolve_body
from vfit_engine.errors import InputError
from vfit_engine.pattern import curves, validate
from vfit_engine.pattern.model import Edge, Pattern
from vfit_engine.pattern.panel_slots import Slot, slot_kind
from vfit_engine.pattern.placement import MAPPED_FRAMES, garmentcode_landmarks, panel_up, place
from vfit_engine.pattern.placement_body import BodyParts

#: The grading rule in words (``vfit size`` prints it; the module docstring is its one long home).
RULE = ("girth growth spread over the panels crossing each girth (bust, waist, hips) in proportion to their width "
        "there, linear in height between the levels; sleeves across by the upper arm's change, their caps' height "
        "kept to their graded armholes; lengths as made")
#: The girth levels of the trunk, top down.
LEVELS = ("bust", "waist", "hips")
#: Kinds of panel that go round an arm (scaled with the upper arm) and bands that take the scale at their height.
ARM_KINDS = ("sleeve", "cuff")
BAND_KINDS = ("collar", "waistband")
#: Outline samples per edge for sections and fits.
PER_EDGE = 48
#: A graded edge is the polyline through its moved points: chords within CHORD_TOL (m) of the curve, at most
#: MAX_STEP (m) apart (the map is smooth, so 5 mm pieces follow it to well under 0.1 mm).
CHORD_TOL = 2e-5
MAX_STEP = 0.005
#: A width scale outside this range is more than one pattern can be graded by (a size far outside the run).
SCALE_RANGE = (0.6, 1.6)
#: A level whose crossing panels sum to less than this share of the body's girth there is left out: the
#: garment does not go round the body there (a waistline a few corners of the panels reach past).
MIN_COVER = 0.5
#: The range searched for a cap's height factor.
CAP_RANGE = (0.25, 4.0)
#: How near (m) the caps must come to their armholes' ease before the sleeve's width is left to the armhole.
ARM_TOL = 5e-4
#: What a pattern's own body must give to be built (GarmentCode's body measurements, cm).
BODY_KEYS = ("height", "bust", "waist", "hips")
#: The girths the rule reads, as :class:`vfit_engine.body.measure.Measurer` names them.
GIRTHS = LEVELS + ("upper-arm",)


@dataclasses.dataclass
class Graded:
    """A graded pattern and what the rule did.

    Attributes
    ----------
    pattern : Pattern
        The graded pattern (a new object; the one given is not changed).
    levels : dict
        Level name -> ``height_m``, ``body_change_cm``, ``garment_cm`` (the pattern's girth there before
        grading), ``scale`` (of the widths of the panels crossing it), ``panels`` (their names).
    arms : list of dict
        Per arm: ``panels``, ``change_cm`` (the upper arm's), ``girth_cm`` (the sleeve's just below its cap),
        ``scale`` (across the arm), ``cap_scale`` (of the cap's height).
    warnings : list of str
        The validation's warnings on the graded pattern.
    """

    pattern: Pattern
    levels: dict
    arms: list
    warnings: list


class _Axis:
    """A panel's vertical axis in its own frame: height = ``xy @ grad + c``, ``across`` at right angles."""

    def __init__(self, xy, heights, where="pattern"):
        a = np.column_stack([xy, np.ones(len(xy))])
        coef = np.linalg.lstsq(a, heights, rcond=None)[0]
        g = coef[:2]
        norm = float(np.linalg.norm(g))
        if norm < 1e-6:
            raise InputError(f"{where}: the panel lies flat across the body's height, so the girth rule cannot tell "
                             f"its vertical axis; fix: place it upright (its translation and rotation)")
        self.grad, self.c = g, float(coef[2])
        self.up = g / norm
        self.across = np.array([self.up[1], -self.up[0]])

    def height(self, xy):
        return np.asarray(xy, float) @ self.grad + self.c


def _outline(panel):
    return panel.outline(PER_EDGE)


def _section_width(poly, level_of, value, across):
    """Width (m) of the closed polygon ``poly`` (k, 2) along ``across`` where ``level_of`` (k,) equals
    ``value``: the inside stretches of the line summed (even-odd, so a concave panel counts each)."""
    f = level_of - value
    g = np.roll(f, -1)
    hit = (f * g < 0) | ((f == 0) & (g != 0))
    if not hit.any():
        return 0.0
    t = f[hit] / (f[hit] - g[hit])
    pts = poly[hit] + t[:, None] * (np.roll(poly, -1, axis=0)[hit] - poly[hit])
    a = np.sort(pts @ across)
    return float((a[1::2] - a[0:len(a) - len(a) % 2:2]).sum())


def _dense(panel, i):
    """Points along edge ``i`` of ``panel``, ends included: chords within :data:`CHORD_TOL` of it, at most
    :data:`MAX_STEP` apart: (k, 2) m."""
    e = panel.edges[i]
    pts = curves.chords(e.kind, panel.edge_ends(i), e.controls, CHORD_TOL)
    steps = np.maximum(np.ceil(np.linalg.norm(np.diff(pts, axis=0), axis=1) / MAX_STEP), 1).astype(int)
    return np.concatenate([a + np.outer(np.arange(n) / n, b - a) for a, b, n in zip(pts[:-1], pts[1:], steps)]
                          + [pts[-1:]])


def _map_points(panel, fn):
    """The panel with every vertex moved by ``fn`` ((k, 2) -> (k, 2)) and every edge redrawn as the polyline
    through its moved points (the map bends straight lines and is not affine, so control points would not do)."""
    vertices = fn(np.asarray(panel.vertices, float))
    edges = []
    for i, e in enumerate(panel.edges):
        inner = fn(_dense(panel, i)[1:-1])
        if e.kind == "line" and _off_chord(inner, vertices[e.start], vertices[e.end]) <= CHORD_TOL:
            edges.append(e)  # still straight: a line (fewer pieces for everything downstream)
            continue
        edges.append(Edge(e.start, e.end, "polyline", tuple(tuple(float(x) for x in p) for p in inner), e.label))
    return dataclasses.replace(panel, vertices=vertices, edges=edges)


def _off_chord(pts, a, b):
    """How far (m) points (k, 2) lie from the line through ``a`` and ``b`` at most (0 for none)."""
    if not len(pts):
        return 0.0
    d = (b - a) / max(float(np.linalg.norm(b - a)), 1e-300)
    w = pts - a
    return float(np.abs(w[:, 0] * d[1] - w[:, 1] * d[0]).max())


def _polyline_length(pts):
    return float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum())


def _kinds(pattern):
    return {name: slot_kind(pattern, name) for name in pattern.panels}


def _arm_groups(pattern, kinds):
    """The arm panels in groups sewn to each other (one group per arm), in the pattern's order."""
    arm = [n for n in pattern.panels if kinds[n] in ARM_KINDS]
    group = {n: {n} for n in arm}
    for st in pattern.stitches:
        a, b = st.a.panel, st.b.panel
        if a in group and b in group and group[a] is not group[b]:
            merged = group[a] | group[b]
            for n in merged:
                group[n] = merged
    seen, out = set(), []
    for n in arm:
        if n not in seen:
            seen |= group[n]
            out.append([m for m in arm if m in group[n]])
    return out


def _trunk_scales(pattern, kinds, height_of, levels):
    """Axes of the trunk panels, the per-level figures and the (heights, scales) the scale is interpolated on."""
    axes, polys, heights = {}, {}, {}
    for name, panel in pattern.panels.items():
        if kinds[name] in ARM_KINDS:
            continue
        poly = _outline(panel)
        h = np.asarray(height_of(name, poly), float)
        axes[name] = _Axis(poly, h, f"{pattern.source or 'pattern'}: panel '{name}'")
        polys[name], heights[name] = poly, h
    out = {}
    for level, (y, girth, change) in levels.items():
        crossing = [n for n in axes if kinds[n] not in BAND_KINDS and heights[n].min() < y < heights[n].max()]
        width = sum(_section_width(polys[n], heights[n], y, axes[n].across) for n in crossing)
        if not crossing or width < MIN_COVER * girth:  # an edge of the garment, not a girth it goes round
            continue
        s = 1.0 + change / width
        if not SCALE_RANGE[0] <= s <= SCALE_RANGE[1]:
            raise InputError(f"{pattern.source or 'pattern'}: grading the {level} from {100 * width:.1f} cm by "
                             f"{100 * change:+.1f} cm scales its panels by {s:.2f}, beyond what one pattern grades "
                             f"to ({SCALE_RANGE[0]}-{SCALE_RANGE[1]}); fix: choose sizes nearer the pattern's own")
        out[level] = dict(height_m=round(float(y), 4), body_change_cm=round(100 * change, 2),
                          garment_cm=round(100 * width, 2), scale=round(s, 5), panels=crossing, _s=s)
    if not out:
        raise InputError(f"{pattern.source or 'pattern'}: no panel crosses the bust, waist or hips of the body it "
                         f"was made for, so the girth rule has nothing to grade by")
    order = sorted(out.values(), key=lambda r: r["height_m"])
    return axes, out, (np.array([r["height_m"] for r in order]), np.array([r["_s"] for r in order]))


def _anchor(axis, poly, x_of, centre_x):
    """Where the panel's widths grow from, along its ``across``: its centre line when it is a front or back
    panel crossing the body's centre line (``x_of``: its points' sideways position on the body), else its
    middle."""
    a = poly @ axis.across
    middle = 0.5 * (a.min() + a.max())
    if x_of is None:
        return middle
    x = np.asarray(x_of, float)
    slope, icpt = np.polyfit(a, x, 1)
    if abs(slope) < 0.7:  # a side panel: it runs round the side, not across the front or back
        return middle
    at = (centre_x - icpt) / slope
    return float(at) if a.min() - 1e-3 <= at <= a.max() + 1e-3 else middle


def _grade_trunk(pattern, kinds, height_of, levels, x_of, centre_x):
    axes, figures, (ys, ss) = _trunk_scales(pattern, kinds, height_of, levels)
    panels = dict(pattern.panels)
    for name, axis in axes.items():
        poly = _outline(pattern.panels[name])
        a0 = _anchor(axis, poly, None if x_of is None else x_of(name, poly), centre_x)

        def move(p, axis=axis, a0=a0):
            s = np.interp(axis.height(p), ys, ss)
            return p + ((s - 1.0) * (p @ axis.across - a0))[:, None] * axis.across

        panels[name] = _map_points(pattern.panels[name], move)
    for r in figures.values():
        r.pop("_s")
    return panels, figures


def _cap_edges(pattern, name, group):
    """(own edge, partner EdgeRef) of the panel's edges sewn to panels outside its arm: its cap."""
    out = []
    for st in pattern.stitches:
        for ref, other in ((st.a, st.b), (st.b, st.a)):
            if ref.panel == name and other.panel not in group:
                out.append((ref.edge, other))
    return out


def _grade_arm(pattern, graded, group, change):
    """Scale one arm's panels across the arm and their caps in height (module docstring, 3); its figures."""
    frames = {}
    for name in group:
        panel = pattern.panels[name]
        up = panel_up(pattern, name, Slot("sleeve"))
        across = np.array([up[1], -up[0]])
        caps = _cap_edges(pattern, name, group)
        poly = _outline(panel)
        u = poly @ up
        cap_pts = [panel.edge_points(e, np.linspace(0.0, 1.0, 17)) for e, _ in caps]
        u0 = float((np.concatenate(cap_pts) @ up).min()) if cap_pts else float(u.max())
        below = u0 - min(0.01, 0.1 * float(np.ptp(u)))
        width = _section_width(poly, u, below, across)
        frames[name] = (up, across, u0, float((poly @ across).mean()), caps, width)
    girth = sum(f[5] for f in frames.values())
    s = 1.0 + change / girth if girth > 0 else 1.0
    if not SCALE_RANGE[0] <= s <= SCALE_RANGE[1]:
        raise InputError(f"{pattern.source or 'pattern'}: grading the sleeve ({', '.join(group)}) from "
                         f"{100 * girth:.1f} cm by {100 * change:+.1f} cm is beyond what one pattern grades to; "
                         f"fix: choose sizes nearer the pattern's own")

    def arm_map(name, k, s):
        up, across, u0, a0 = frames[name][:4]

        def fn(p):
            u, a = p @ up, p @ across
            u2 = np.where(u > u0, u0 + k * (u - u0), u)
            return np.outer(u2, up) + np.outer(a0 + s * (a - a0), across)
        return fn

    pairs = [(name, e, other) for name, f in frames.items() for e, other in f[4]]
    before = sum(pattern.panels[n].edge_length(e) - pattern.edge_length(o) for n, e, o in pairs)
    armholes = sum(graded[o.panel].edge_length(o.edge) for _, _, o in pairs)
    caps = [(n, _dense(pattern.panels[n], e)) for n, e, _ in pairs]

    def excess(k, s):
        return sum(_polyline_length(arm_map(n, k, s)(pts)) for n, pts in caps) - armholes - before

    k, bound = 1.0, "upper arm"
    if pairs:
        k = _increasing_root(lambda x: excess(x, s), *CAP_RANGE)
        if abs(excess(k, s)) > ARM_TOL:  # a flat cap: only the sleeve's width can keep it to its armhole
            k, bound = 1.0, "armhole"
            s = _increasing_root(lambda x: excess(k, x), *SCALE_RANGE)
    graded.update({n: _map_points(pattern.panels[n], arm_map(n, k, s)) for n in group})
    return dict(panels=list(group), change_cm=round(100 * change, 2), girth_cm=round(100 * girth, 2),
                scale=round(s, 5), cap_scale=round(k, 5), width_by=bound)


def _increasing_root(f, lo, hi, steps=40):
    """The root of an increasing ``f`` in [lo, hi] by bisection; the nearer end when it has none there."""
    f_lo, f_hi = f(lo), f(hi)
    if f_lo >= 0.0 or f_hi <= 0.0:
        return lo if abs(f_lo) < abs(f_hi) else hi
    for _ in range(steps):
        mid = 0.5 * (lo + hi)
        if f(mid) > 0.0:
            hi = mid
        else:
            lo = mid
    return 0.5 * (lo + hi)


def grade(pattern, height_of, levels, arm_change=0.0, x_of=None, centre_x=0.0):
    """Grade ``pattern`` by the rule of the module docstring.

    Parameters
    ----------
    pattern : Pattern
    height_of : callable
        ``height_of(panel name, points (k, 2) m in the panel's frame) -> (k,)`` heights (m) of those points on
        the body the pattern was made for (its frame's ``y``, or its placement's).
    levels : dict
        Level name (:data:`LEVELS`) -> ``(height m, girth m, girth change m)``: where the made-for body's
        girth is, how long it is and how much the target body's differs.
    arm_change : float, m
        The upper arm's girth change.
    x_of : callable or None
        ``x_of(panel name, points (k, 2)) -> (k,)`` their sideways position (m) on that body, for the centre
        line (None: every panel grows about its middle).
    centre_x : float, m
        The body's centre line.

    Returns
    -------
    Graded

    Raises
    ------
    InputError
        A change beyond :data:`SCALE_RANGE`, no panel crossing a level, or a graded pattern that does not
        validate.
    """
    kinds = _kinds(pattern)
    panels, figures = _grade_trunk(pattern, kinds, height_of, levels, x_of, centre_x)
    arms = [_grade_arm(pattern, panels, group, arm_change) for group in _arm_groups(pattern, kinds)]
    graded = dataclasses.replace(pattern, panels=panels, stitches=list(pattern.stitches),
                                 warnings=list(pattern.warnings), body=dict(pattern.body))
    warnings = validate.validate(graded)
    return Graded(graded, figures, arms, warnings)


def stitch_drift(original, graded):
    """Per stitch, how much further apart (m) its two edges' lengths are after grading than before:
    ``|la' - lb'| - |la - lb|`` (negative: closer)."""
    out = []
    for st in original.stitches:
        before = abs(original.edge_length(st.a) - original.edge_length(st.b))
        after = abs(graded.edge_length(st.a) - graded.edge_length(st.b))
        out.append(after - before)
    return np.array(out)


@dataclasses.dataclass
class MadeFor:
    """The body a pattern was made for, as the rule reads it.

    Attributes
    ----------
    body : Body
        vfit's body built to the pattern's own body measurements, else the default body of ``gender``.
    gender : str or float
    text : str
        "made for: ..." in words (assumed or named).
    girths : dict
        :data:`GIRTHS` name -> m (iso; a man's bust is his chest).
    heights : dict
        :data:`LEVELS` name -> height (m) of that girth's plane on ``body``.
    """

    body: Body
    gender: object
    text: str
    girths: dict
    heights: dict


def made_for(pattern, model, gender=None, measurer=None):
    """The body ``pattern`` was made for: its own (GarmentCode's body measurements, built by vfit's morph),
    else the default body of ``gender``, said to be assumed.

    Raises
    ------
    InputError
        The pattern names no body and ``gender`` is None.
    """
    own = pattern.body or {}
    if all(k in own for k in BODY_KEYS):
        g = gender or "female"
        body = resolve_body(model, targets={k: own[k] / 100.0 for k in BODY_KEYS}, gender=g)
        text = (f"made for: the pattern's own body (height {own['height']:.1f}, bust {own['bust']:.1f}, waist "
                f"{own['waist']:.1f}, hips {own['hips']:.1f} cm), built as a {g} body")
    elif gender is None:
        raise InputError(f"{pattern.source or 'pattern'}: the pattern names no body it was made for and no gender "
                         f"is given to assume one; fix: give the gender (--gender female or male)")
    else:
        g = gender
        body = default_body(model, g)
        text = f"made for: unknown (the pattern names no body), assumed the default {g} body"
    m = (measurer or Measurer(model)).measure(body.verts, names=GIRTHS, mass=False, gender=g)
    return MadeFor(body, g, text, {k: float(m.values[k]) for k in GIRTHS},
                   {k: float(m.planes[k]) for k in LEVELS})


def grade_to_body(pattern, made, target, model, measurer=None, arrange="auto"):
    """``pattern`` graded from the body it was made for (``made``: :func:`made_for`) to ``target`` (a Body).

    The heights are the pattern frame's, at its body's landmarks, for a frame vfit maps (GarmentCode's),
    else the panels' on ``made.body`` as :func:`vfit_engine.pattern.placement.place` wraps them round the
    body part each belongs to; the girth changes are
    ``target``'s iso girths less ``made``'s. A pattern naming its own body names ``target``'s girths in the
    graded copy (its placement maps widths by them).

    Returns
    -------
    Graded
    """
    m = (measurer or Measurer(model)).measure(target.verts, names=GIRTHS, mass=False, gender=made.gender)
    change = {k: float(m.values[k]) - made.girths[k] for k in GIRTHS}
    if pattern.frame in MAPPED_FRAMES and arrange != "wrap":  # heights in the frame, at its body's landmarks
        _, at = garmentcode_landmarks(pattern.body)
        heights = {k: at[k][0] for k in LEVELS}
        height_of = lambda n, xy: pattern.panels[n].to_3d(xy)[:, 1]  # noqa: E731
        x_of, centre_x = (lambda n, xy: pattern.panels[n].to_3d(xy)[:, 0]), 0.0
    else:  # heights on the made-for body where the panels are placed round it
        parts = BodyParts.from_model(model, made.body.verts)
        placement = place(pattern, parts, arrange=arrange)
        heights = made.heights
        height_of = lambda n, xy: placement.raw(n, xy)[:, 1]  # noqa: E731
        x_of, centre_x = (lambda n, xy: placement.raw(n, xy)[:, 0]), parts.levels["center_x"]
    levels = {k: (heights[k], made.girths[k], change[k]) for k in LEVELS}
    graded = grade(pattern, height_of, levels, change["upper-arm"], x_of=x_of, centre_x=centre_x)
    if graded.pattern.body:
        graded.pattern.body.update({k: round(100.0 * float(m.values[k]), 3) for k in LEVELS})
    return graded
