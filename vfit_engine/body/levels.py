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
        return self.runs_at([y], tol)[0]

    def runs_at(self, ys, tol=0.002):
        """The runs of :meth:`runs` at every height of ``ys`` at once.

        One pass over the triangles instead of one per height: the level scans ask for a few hundred
        heights, and a height at a time spent most of its time on per-call overhead and on masking
        every triangle below it.

        Returns
        -------
        runs : (r, 2) float64, m
        owner : (r,) int64
            Index into ``ys`` of each run; the runs of one height are left to right.
        """
        ys = np.asarray(ys, dtype=np.float64).ravel()
        order = np.argsort(ys, kind="stable")
        ys_s = ys[order]
        # the (triangle, height) pairs with lo < y < hi: the heights strictly inside a triangle's span
        first = np.searchsorted(ys_s, self.lo, side="right")
        count = np.maximum(np.searchsorted(ys_s, self.hi, side="left") - first, 0)
        tri = np.repeat(np.arange(count.size), count)
        if not tri.size:
            return np.zeros((0, 2)), np.zeros(0, np.int64)
        k = np.arange(tri.size) - np.repeat(np.cumsum(count) - count, count) + first[tri]
        lo, hi = _crossing_intervals(self.t[tri], ys_s[k])
        # by height, then left to right (two argsorts: faster than np.lexsort here)
        o = np.argsort(lo)
        o = o[np.argsort(k[o], kind="stable")]
        k, lo, hi = k[o], lo[o], hi[o]
        # a run ends where the next interval starts beyond the furthest end so far (the run's own end: every
        # earlier run ended before this one began); every height starts a run of its own
        start = np.ones(lo.size, dtype=bool)
        start[1:] = (k[1:] != k[:-1]) | (lo[1:] > _cummax_by_group(hi, k)[:-1] + tol)
        starts = np.flatnonzero(start)
        return np.stack([lo[starts], np.maximum.reduceat(hi, starts)], axis=1), order[k[starts]]

    def central_widths(self, ys, x_c, tol=0.002):
        """(len(ys),) width (m) of the run holding ``x = x_c`` at every height of ``ys``, NaN where none."""
        runs, owner = self.runs_at(ys, tol)
        hit = (runs[:, 0] <= x_c) & (x_c <= runs[:, 1])
        out = np.full(np.size(ys), np.nan)
        out[owner[hit]] = runs[hit, 1] - runs[hit, 0]
        return out

    def central_run(self, y, x_c):
        """The run (x0, x1) m at height ``y`` that holds ``x = x_c``, or None."""
        for a, b in self.runs(y):
            if a <= x_c <= b:
                return a, b
        return None


def _crossing_intervals(t, y):
    """x-interval (lo, hi) where each triangle (p, 3, 3) crosses its plane ``y`` (p,)."""
    xs = np.full((t.shape[0], 3), np.nan)
    for k, (i, j) in enumerate(((0, 1), (1, 2), (2, 0))):
        a, b = t[:, i], t[:, j]
        cross = (a[:, 1] - y) * (b[:, 1] - y) < 0
        s = np.where(cross, (y - a[:, 1]) / np.where(cross, b[:, 1] - a[:, 1], 1.0), 0.0)
        xs[:, k] = np.where(cross, a[:, 0] + s * (b[:, 0] - a[:, 0]), np.nan)
    # fmin/fmax skip the NaN of the edge that does not cross: nanmin/nanmax's values, without their copies
    return np.fmin(np.fmin(xs[:, 0], xs[:, 1]), xs[:, 2]), np.fmax(np.fmax(xs[:, 0], xs[:, 1]), xs[:, 2])


def _cummax_by_group(x, group):
    """Running maximum of ``x`` restarting at each new value of the sorted labels ``group``.

    Done on the ranks of the values, offset by group, so that one ``np.maximum.accumulate`` serves all
    groups and the maxima are the values themselves (an offset added to the floats would round them).
    """
    vals, rank = np.unique(x, return_inverse=True)
    offset = group * vals.size
    return vals[np.maximum.accumulate(offset + rank.ravel()) - offset]


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
    apart = np.bincount(sec.runs_at(ys)[1], minlength=ys.size) >= 3
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
    widths = sec.central_widths(ys_up, x_c)
    if np.isfinite(widths).any():
        out["neck_y"] = float(ys_up[np.nanargmin(widths)])
    below = np.arange(armpit, y0, -SCAN_STEP)
    # all heights at once (cheaper than stopping early a height at a time); the legs part at the first gap
    widths_below = sec.central_widths(below, x_c)
    gap = np.flatnonzero(np.isnan(widths_below))
    if gap.size:
        out["crotch_y"] = float(below[gap[0]])
        widths_below = widths_below[:gap[0]]
    if np.isfinite(out["crotch_y"]) and widths_below.size:
        n = widths_below.size
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
