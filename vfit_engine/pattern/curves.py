"""The curve an edge of a panel follows: a line, a quadratic or cubic Bezier, a circular arc, or a polyline.

Every curve is given by absolute 2D points in the panel's frame (metres): its two ends and, for a Bezier, its
control points; an arc is given by its ends and its midpoint (the point on the arc halfway along it), which fixes
the circle and the side it bulges to without flags; a polyline by the points it passes through between its ends,
in order (a DXF outline is a polyline, so the edges read from one are). Evaluation is by arc length, so that points spaced evenly
along one edge land evenly along the edge it is sewn to.
"""

import math

import numpy as np

KINDS = ("line", "quadratic", "cubic", "circle", "polyline")

_DENSE = 512  # polyline samples per edge for arc-length lookups: far below a millimetre on any garment edge


def bezier_points(ctrl, t):
    """Points at parameters ``t`` (m,) of the Bezier with control polygon ``ctrl`` (k, 2), by de Casteljau."""
    t = np.asarray(t, float)[:, None]
    pts = [np.broadcast_to(np.asarray(c, float), (len(t), 2)) for c in ctrl]
    while len(pts) > 1:
        pts = [(1.0 - t) * a + t * b for a, b in zip(pts[:-1], pts[1:])]
    return np.array(pts[0])


def circle_through(a, m, b):
    """Centre and radius of the circle through ``a``, ``m`` and ``b``; None when the three are in a line."""
    a, m, b = (np.asarray(p, float) for p in (a, m, b))
    d = 2.0 * ((a[0] - b[0]) * (m[1] - b[1]) - (m[0] - b[0]) * (a[1] - b[1]))
    scale = max(np.ptp(np.stack([a, m, b]), axis=0).max(), 1e-300)
    if abs(d) < 1e-12 * scale * scale:
        return None
    aa, mm, bb = a @ a, m @ m, b @ b
    cx = (aa * (m[1] - b[1]) + mm * (b[1] - a[1]) + bb * (a[1] - m[1])) / d
    cy = (aa * (b[0] - m[0]) + mm * (a[0] - b[0]) + bb * (m[0] - a[0])) / d
    c = np.array([cx, cy])
    return c, float(np.linalg.norm(a - c))


def _arc_points(a, m, b, t):
    """Points at fractions ``t`` of the arc from ``a`` through ``m`` to ``b`` (uniform in angle = in length)."""
    circle = circle_through(a, m, b)
    if circle is None:
        return np.asarray(a, float) + np.asarray(t, float)[:, None] * (np.asarray(b, float) - a)
    c, r = circle
    ang = [math.atan2(p[1] - c[1], p[0] - c[0]) for p in (a, m, b)]
    sweep = (ang[2] - ang[0]) % (2 * math.pi)          # counter-clockwise from a to b
    if (ang[1] - ang[0]) % (2 * math.pi) > sweep:       # m is not on that way round: go clockwise
        sweep -= 2 * math.pi
    th = ang[0] + np.asarray(t, float) * sweep
    return np.column_stack([c[0] + r * np.cos(th), c[1] + r * np.sin(th)])


def _polyline_vertices(ends, controls):
    """The polyline's corners, ends included: (k + 2, 2)."""
    inner = np.asarray(controls, float).reshape(-1, 2)
    return np.vstack([np.asarray(ends[0], float), inner, np.asarray(ends[1], float)])


def _along(pts, s):
    """Points at arc-length fractions ``s`` of the polyline through ``pts`` (k, 2)."""
    cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
    target = np.asarray(s, float) * cum[-1]
    return np.column_stack([np.interp(target, cum, pts[:, 0]), np.interp(target, cum, pts[:, 1])])


def curve_points(kind, ends, controls, t):
    """Points at curve parameters ``t`` in [0, 1] (not arc length, except for lines, arcs and polylines)."""
    a, b = np.asarray(ends[0], float), np.asarray(ends[1], float)
    if kind == "polyline":
        return _along(_polyline_vertices(ends, controls), t)
    if kind == "line":
        return a + np.asarray(t, float)[:, None] * (b - a)
    if kind in ("quadratic", "cubic"):
        return bezier_points([a, *controls, b], t)
    if kind == "circle":
        return _arc_points(a, controls[0], b, t)
    raise ValueError(f"unknown curve kind {kind!r}")


def polyline(kind, ends, controls, n=_DENSE):
    """A dense polyline along the curve, ends included: (n + 1, 2)."""
    return curve_points(kind, ends, controls, np.linspace(0.0, 1.0, n + 1))


def length(kind, ends, controls):
    """Arc length of the curve (exact for lines and arcs, to well under 1e-5 relative for Beziers)."""
    if kind == "line":
        return float(np.linalg.norm(np.asarray(ends[1], float) - ends[0]))
    if kind == "circle":
        circle = circle_through(ends[0], controls[0], ends[1])
        if circle is None:
            return length("line", ends, ())
        c, r = circle
        p = _arc_points(ends[0], controls[0], ends[1], np.array([0.0, 1.0 / 3.0]))
        # the sweep from the parametrisation: three times the angle covered by the first third
        v0, v1 = p[0] - c, p[1] - c
        third = math.atan2(v0[0] * v1[1] - v0[1] * v1[0], v0 @ v1)
        return abs(3.0 * third) * r
    if kind == "polyline":
        return float(np.linalg.norm(np.diff(_polyline_vertices(ends, controls), axis=0), axis=1).sum())
    pts = polyline(kind, ends, controls)
    return float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum())


def sample(kind, ends, controls, s):
    """Points at arc-length fractions ``s`` (m,) in [0, 1] of the curve: s = 0.5 is halfway along its length."""
    s = np.asarray(s, float)
    if kind in ("line", "circle", "polyline"):
        return curve_points(kind, ends, controls, s)   # all three are uniform in length already
    return _along(polyline(kind, ends, controls), s)


def chords(kind, ends, controls, tol=1e-4):
    """Points along the curve, ends included, whose chords stray at most ``tol`` (m) from it: (k, 2).

    Lines and polylines give their own corners; other curves are halved until the sagitta (the curve's point
    halfway along a piece against its chord's midpoint, the largest gap of a smooth arc) is within ``tol``.
    """
    if kind == "line":
        return np.array([ends[0], ends[1]], float)
    if kind == "polyline":
        return _polyline_vertices(ends, controls)
    n = 8
    while True:
        s = np.linspace(0.0, 1.0, n + 1)
        pts = sample(kind, ends, controls, s)
        mids = sample(kind, ends, controls, 0.5 * (s[:-1] + s[1:]))
        if np.linalg.norm(mids - 0.5 * (pts[:-1] + pts[1:]), axis=1).max() <= tol or n >= 8192:
            return pts
        n *= 2
