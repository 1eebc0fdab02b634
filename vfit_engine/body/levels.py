"""Body levels (armpit, neck, waist, crotch) from horizontal sections of the body surface.

The levels follow a morphed body without landmarks: for a height ``y`` the triangles crossing the
plane give x-intervals which are merged into connected runs (:class:`Sections`).

* armpit level: between 55 % and 85 % of the height, the top of the longest stretch of sections
  with three or more runs (torso and both arms apart, A-pose); shoulder bumps just below the neck
  or the hands give only short stretches;
* neck level: the narrowest central run between the armpit level and 60 % of the way to the top;
* crotch level: scanning down from the armpit level, the first ``y`` where the body centre line is
  not covered (the legs have separated);
* waist level: the narrowest central run between crotch and armpit (searched in the middle 10-90 %).

The central run at a height is the run holding the centre line ``x = center_x`` (the median x of
the surface); :func:`body_center_xz` places the centre line in z too.
"""
from __future__ import annotations

import numpy as np

#: Vertical step of the section scans, m.
SCAN_STEP = 0.005


class Sections:
    """Horizontal sections of a triangle surface (triangles gathered once, sorted by their low Y).

    Parameters
    ----------
    verts : (N, 3) float64, m
    tris : (T, 3) int64
    """

    def __init__(self, verts, tris):
        t = np.asarray(verts, dtype=np.float64)[np.asarray(tris, dtype=np.int64)]
        lo = t[:, :, 1].min(1)
        order = np.argsort(lo)
        self.t = t[order]
        self.lo = lo[order]
        self.hi = t[order][:, :, 1].max(1)

    def runs(self, y, tol=0.002):
        """Merged x-intervals (r, 2) m of the section at height ``y``, left to right.

        Intervals less than ``tol`` (m) apart are merged.
        """
        n = int(np.searchsorted(self.lo, y))
        m = self.hi[:n] > y
        if not m.any():
            return np.zeros((0, 2))
        t = self.t[:n][m]
        xs = np.full((t.shape[0], 3), np.nan)
        for k, (i, j) in enumerate(((0, 1), (1, 2), (2, 0))):
            a, b = t[:, i], t[:, j]
            cross = (a[:, 1] - y) * (b[:, 1] - y) < 0
            s = np.where(cross, (y - a[:, 1]) / np.where(cross, b[:, 1] - a[:, 1], 1.0), 0.0)
            xs[:, k] = np.where(cross, a[:, 0] + s * (b[:, 0] - a[:, 0]), np.nan)
        lo, hi = np.nanmin(xs, 1), np.nanmax(xs, 1)
        order = np.argsort(lo)
        lo, hi = lo[order], hi[order]
        # a run ends where the next interval starts beyond the furthest end so far (the run's own end: every
        # earlier run ended before this one began)
        start = np.ones(lo.size, dtype=bool)
        start[1:] = lo[1:] > np.maximum.accumulate(hi)[:-1] + tol
        first = np.flatnonzero(start)
        return np.stack([lo[first], np.maximum.reduceat(hi, first)], axis=1)

    def central_run(self, y, x_c):
        """The run (x0, x1) m at height ``y`` that holds ``x = x_c``, or None."""
        for a, b in self.runs(y):
            if a <= x_c <= b:
                return a, b
        return None


def body_levels(body_verts, body_tris, sections=None):
    """Armpit, neck, waist and crotch heights of a body in A-pose (see the module docstring).

    Parameters
    ----------
    body_verts : (N, 3) float64, m
    body_tris : (T, 3) int64
        Triangles of the visible body surface.
    sections : Sections or None
        ``Sections(body_verts, body_tris)`` if the caller has it already.

    Returns
    -------
    dict
        ``y_min``, ``y_max``, ``height``, ``armpit_y``, ``neck_y``, ``waist_y``, ``crotch_y`` (m),
        ``center_x`` (m). A level that could not be found is NaN.
    """
    v = np.asarray(body_verts, dtype=np.float64)
    tris = np.asarray(body_tris, dtype=np.int64)
    return _levels(v[np.unique(tris)], Sections(v, tris) if sections is None else sections)


def _levels(surf, sec):
    y0, y1 = float(surf[:, 1].min()), float(surf[:, 1].max())
    h = y1 - y0
    x_c = float(np.median(surf[:, 0]))
    out = dict(y_min=y0, y_max=y1, height=h, center_x=x_c, armpit_y=np.nan, neck_y=np.nan,
               waist_y=np.nan, crotch_y=np.nan)
    # armpit: top of the longest stretch of sections with the arms apart (>= 3 runs) in the
    # upper body; shoulder bumps or hands give short stretches only
    ys = np.arange(y0 + 0.55 * h, y0 + 0.85 * h, SCAN_STEP)
    apart = np.array([len(sec.runs(y)) >= 3 for y in ys])
    if not apart.any():
        return out
    best_len, best_top, run_len = 0, None, 0
    for i, a in enumerate(apart):
        run_len = run_len + 1 if a else 0
        if run_len > best_len:
            best_len, best_top = run_len, i
    armpit = float(ys[best_top])
    out["armpit_y"] = armpit
    ys_up = np.arange(armpit, armpit + 0.6 * (y1 - armpit), SCAN_STEP)
    widths = []
    for y in ys_up:
        r = sec.central_run(y, x_c)
        widths.append(np.nan if r is None else r[1] - r[0])
    if np.isfinite(widths).any():
        out["neck_y"] = float(ys_up[np.nanargmin(widths)])
    below = np.arange(armpit, y0, -SCAN_STEP)
    widths_below = []
    for y in below:
        r = sec.central_run(y, x_c)
        if r is None:
            out["crotch_y"] = float(y)
            break
        widths_below.append(r[1] - r[0])
    if np.isfinite(out["crotch_y"]) and widths_below:
        n = len(widths_below)
        lo, hi = int(0.1 * n), max(int(0.9 * n), int(0.1 * n) + 1)
        out["waist_y"] = float(below[lo + int(np.argmin(widths_below[lo:hi]))])
    return out


def body_center_xz(surf, sections, x_c, y, half=0.02):
    """The body centre line at height ``y``: (x_c, median z of the surface near y in the central run).

    Parameters
    ----------
    surf : (s, 3) float64, m
        Vertices of the body surface (those the sectioned triangles use).
    sections : Sections
        Of that surface.
    x_c : float, m
        Centre line x (``body_levels(...)["center_x"]``).
    y : float, m
    half : float, m
        Half height of the slab of surface vertices whose z is taken.

    Returns
    -------
    (2,) float64, m
        (x, z); the median z of the slab, or of the whole surface where the slab is empty.
    """
    slab = surf[np.abs(surf[:, 1] - y) <= half]
    r = sections.central_run(y, x_c)
    if r is not None:
        inside = slab[(slab[:, 0] >= r[0]) & (slab[:, 0] <= r[1])]
        if len(inside):
            slab = inside
    z = float(np.median(slab[:, 2])) if len(slab) else float(np.median(surf[:, 2]))
    return np.array([x_c, z])
