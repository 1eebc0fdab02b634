"""Automatic pin selection for garments and attachment of pins to the body surface.

A pinned garment vertex follows a fixed point of the body surface (a triangle and barycentric
coordinates) instead of being simulated; that is what holds trousers up and a top on the shoulders.

Body levels (``body_levels``) come from horizontal sections of the body surface, so they follow a
morphed body without landmarks: for a height ``y`` the triangles crossing the plane give x-intervals
which are merged into connected runs.

* armpit level: between 55 % and 85 % of the height, the top of the longest stretch of sections
  with three or more runs (torso and both arms apart, A-pose); shoulder bumps just below the neck
  or the hands give only short stretches;
* neck level: the narrowest central run between the armpit level and 60 % of the way to the top;
* crotch level: scanning down from the armpit level, the first ``y`` where the body centre line is
  not covered (the legs have separated);
* waist level: the narrowest central run between crotch and armpit (searched in the middle 10-90 %).

Pins per piece (``auto_pins``):

* bottom (trousers, skirt; the piece stays below the armpit level): the open boundary loop (edges
  used by one face) with the highest mean height among the loops whose XZ projection winds around
  the body's centre line at that height (waistband; ankle and leg hems do not encircle it);
* top (the piece reaches above the armpit level): the shoulder region is the body surface between
  the armpit and neck levels that faces up (vertex normal Y >= ``SHOULDER_MIN_NORMAL_Y`` = 0.7,
  i.e. within 45 degrees of vertical: the top of the shoulders and the trapezius; 0.5 also took
  the upper back and the top of the bust). Pins are the piece's vertices above the armpit level
  whose nearest body vertex is in that region and at most ``SHOULDER_MAX_DIST`` away.
  A top with no such vertex (strapless) falls back to the bottom rule (its upper hem).
"""
from __future__ import annotations

import numpy as np

#: Smallest Y component of the body normal counted as "facing up" in the shoulder region.
SHOULDER_MIN_NORMAL_Y = 0.7
#: Largest garment-to-body distance of a shoulder pin, m.
SHOULDER_MAX_DIST = 0.04
#: A piece reaching this far above the armpit level is a top, m.
TOP_MARGIN = 0.02
#: Vertical step of the section scans, m.
SCAN_STEP = 0.005


class _Sections:
    """Horizontal sections of a triangle surface (triangles gathered once, sorted by their low Y)."""

    def __init__(self, verts, tris):
        t = np.asarray(verts, dtype=np.float64)[np.asarray(tris, dtype=np.int64)]
        lo = t[:, :, 1].min(1)
        order = np.argsort(lo)
        self.t = t[order]
        self.lo = lo[order]
        self.hi = t[order][:, :, 1].max(1)

    def runs(self, y, tol=0.002):
        """Merged x-intervals (r, 2) of the section at height ``y``, left to right."""
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
        runs = []
        for a, b in zip(lo[order].tolist(), hi[order].tolist()):
            if runs and a <= runs[-1][1] + tol:
                runs[-1][1] = max(runs[-1][1], b)
            else:
                runs.append([a, b])
        return np.array(runs)


def _central_run(runs, x_c):
    for a, b in runs:
        if a <= x_c <= b:
            return a, b
    return None


def body_levels(body_verts, body_tris):
    """Armpit, neck, waist and crotch heights of a body in A-pose (see the module docstring).

    Parameters
    ----------
    body_verts : (N, 3) float64, m
    body_tris : (T, 3) int64
        Triangles of the visible body surface.

    Returns
    -------
    dict
        ``y_min``, ``y_max``, ``height``, ``armpit_y``, ``neck_y``, ``waist_y``, ``crotch_y`` (m),
        ``center_x`` (m). A level that could not be found is NaN.
    """
    v = np.asarray(body_verts, dtype=np.float64)
    tris = np.asarray(body_tris, dtype=np.int64)
    return _levels(v[np.unique(tris)], _Sections(v, tris))


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
        r = _central_run(sec.runs(y), x_c)
        widths.append(np.nan if r is None else r[1] - r[0])
    if np.isfinite(widths).any():
        out["neck_y"] = float(ys_up[np.nanargmin(widths)])
    below = np.arange(armpit, y0, -SCAN_STEP)
    widths_below = []
    for y in below:
        r = _central_run(sec.runs(y), x_c)
        if r is None:
            out["crotch_y"] = float(y)
            break
        widths_below.append(r[1] - r[0])
    if np.isfinite(out["crotch_y"]) and widths_below:
        n = len(widths_below)
        lo, hi = int(0.1 * n), max(int(0.9 * n), int(0.1 * n) + 1)
        out["waist_y"] = float(below[lo + int(np.argmin(widths_below[lo:hi]))])
    return out


def vertex_normals(verts, tris):
    """(n, 3) unit area-weighted vertex normals, oriented outward (away from the centroid on average)."""
    v = np.asarray(verts, dtype=np.float64)
    fn = np.cross(v[tris[:, 1]] - v[tris[:, 0]], v[tris[:, 2]] - v[tris[:, 0]])
    n = np.zeros_like(v)
    for k in range(3):
        np.add.at(n, tris[:, k], fn)
    used = np.unique(tris)
    c = v[used].mean(0)
    if np.sum(n[used] * (v[used] - c)) < 0:
        n = -n
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    return n / np.where(norm > 0, norm, 1.0)


def boundary_loops(mesh, vertex_mask=None):
    """Closed loops of boundary edges (edges used by exactly one face).

    Parameters
    ----------
    mesh : MeshData
    vertex_mask : (n,) bool or None
        Keep only edges whose both ends are in the mask (one garment piece).

    Returns
    -------
    list of (L,) int64
        Vertex indices in walking order; open chains (non-manifold borders) are returned too.
    """
    e = mesh.boundary_edges()
    if vertex_mask is not None and len(e):
        e = e[vertex_mask[e[:, 0]] & vertex_mask[e[:, 1]]]
    adj = {}
    for a, b in e.tolist():
        adj.setdefault(a, []).append(b)
        adj.setdefault(b, []).append(a)
    seen_edges = set()
    loops = []
    for start in sorted(adj):
        for nb in adj[start]:
            if (min(start, nb), max(start, nb)) in seen_edges:
                continue
            loop = [start]
            prev, cur = start, nb
            seen_edges.add((min(prev, cur), max(prev, cur)))
            while cur != start:
                loop.append(cur)
                nxt = [w for w in adj[cur] if (min(cur, w), max(cur, w)) not in seen_edges]
                if not nxt:
                    break
                prev, cur = cur, nxt[0]
                seen_edges.add((min(prev, cur), max(prev, cur)))
            loops.append(np.array(loop, dtype=np.int64))
    return loops


def winding_number(points_xz, center_xz):
    """Winding number of the closed polygon (L, 2) around ``center_xz`` (2,)."""
    d = np.asarray(points_xz, dtype=np.float64) - np.asarray(center_xz, dtype=np.float64)
    ang = np.arctan2(d[:, 1], d[:, 0])
    step = np.diff(np.concatenate([ang, ang[:1]]))
    step = (step + np.pi) % (2 * np.pi) - np.pi
    return float(step.sum() / (2 * np.pi))


def _body_center_xz(surf, sec, x_c, y, half=0.02):
    """Body centre line at height y: (x_c, median z of the surface near y inside the central run)."""
    slab = surf[np.abs(surf[:, 1] - y) <= half]
    r = _central_run(sec.runs(y), x_c)
    if r is not None:
        inside = slab[(slab[:, 0] >= r[0]) & (slab[:, 0] <= r[1])]
        if len(inside):
            slab = inside
    z = float(np.median(slab[:, 2])) if len(slab) else float(np.median(surf[:, 2]))
    return np.array([x_c, z])


def _waist_loop(mesh, mask, surf, sec, x_c):
    """Highest boundary loop of the piece that winds around the body centre line, or None."""
    best = None
    for loop in boundary_loops(mesh, mask):
        if len(loop) < 3:
            continue
        p = mesh.verts[loop]
        y = float(p[:, 1].mean())
        w = winding_number(p[:, [0, 2]], _body_center_xz(surf, sec, x_c, y))
        if abs(w) > 0.5 and (best is None or y > best[1]):
            best = (loop, y)
    return best


def _shoulder_pins(mesh, mask, v, surf_idx, normals, levels):
    from scipy.spatial import cKDTree

    lo, hi = levels["armpit_y"], levels["neck_y"]
    if not (np.isfinite(lo) and np.isfinite(hi)):
        return np.zeros(0, np.int64)
    sv = v[surf_idx]
    region = (sv[:, 1] >= lo) & (sv[:, 1] <= hi) & (normals[surf_idx, 1] >= SHOULDER_MIN_NORMAL_Y)
    idx = np.flatnonzero(mask)
    gp = mesh.verts[idx]
    cand = gp[:, 1] >= lo
    if not cand.any():
        return np.zeros(0, np.int64)
    dist, near = cKDTree(sv).query(gp[cand])
    ok = region[near] & (dist <= SHOULDER_MAX_DIST)
    return idx[cand][ok]


def auto_pins(mesh, body_verts, body_tris, kind="auto", pieces=None):
    """Pick the garment vertices to pin to the body, piece by piece.

    Parameters
    ----------
    mesh : MeshData
        Garment in m, placed on the body (same frame as ``body_verts``).
    body_verts : (N, 3) float64, m
    body_tris : (T, 3) int64
        Visible body surface triangles.
    kind : {"auto", "top", "bottom"}
        ``auto`` decides per piece: a piece reaching ``TOP_MARGIN`` above the armpit level is a top.
    pieces : (n,) int64 or None
        Piece label per garment vertex (computed from the topology when None).

    Returns
    -------
    pin_idx : (p,) int64
        Sorted unique garment vertex indices.
    info : dict
        ``levels`` (``body_levels``) and ``pieces``: one dict per piece with ``piece``, ``kind``,
        ``method`` (``waist_loop``, ``shoulders``, ``top_band`` or ``none``), ``n_verts``, ``n_pins``,
        ``mean_y``/``min_y``/``max_y`` of the pins (m), and ``warnings``.
    """
    if kind not in ("auto", "top", "bottom"):
        raise ValueError(f"kind must be auto, top or bottom, not {kind!r}")
    from vfit_engine.garment.garment import piece_labels

    v = np.asarray(body_verts, dtype=np.float64)
    tris = np.asarray(body_tris, dtype=np.int64)
    surf_idx = np.unique(tris)
    surf = v[surf_idx]
    sec = _Sections(v, tris)
    levels = _levels(surf, sec)
    normals = vertex_normals(v, tris)
    if pieces is None:
        pieces = piece_labels(mesh.n_verts, mesh.edges())
    info = {"levels": levels, "pieces": [], "warnings": []}
    used = np.zeros(mesh.n_verts, dtype=bool)
    used[mesh.face_verts] = True
    all_pins = []
    for k in range(int(pieces.max()) + 1 if pieces.size else 0):
        mask = (pieces == k) & used
        if not mask.any():
            continue  # isolated vertex: nothing to hold
        top_y = float(mesh.verts[mask, 1].max())
        pkind = kind
        if kind == "auto":
            is_top = np.isfinite(levels["armpit_y"]) and top_y > levels["armpit_y"] + TOP_MARGIN
            pkind = "top" if is_top else "bottom"
        pins, method = np.zeros(0, np.int64), "none"
        if pkind == "top":
            pins = _shoulder_pins(mesh, mask, v, surf_idx, normals, levels)
            method = "shoulders"
        if len(pins) == 0:
            found = _waist_loop(mesh, mask, surf, sec, levels["center_x"])
            if found is not None:
                pins, method = np.unique(found[0]), "waist_loop"
        if len(pins) == 0:
            # last resort: the top centimetre of the piece, so it cannot fall off
            idx = np.flatnonzero(mask)
            pins = idx[mesh.verts[idx, 1] >= top_y - 0.01]
            method = "top_band"
            info["warnings"].append(f"piece {k}: no waist loop or shoulder contact; pinned its top band")
        py = mesh.verts[pins, 1]
        info["pieces"].append(dict(
            piece=k, kind=pkind, method=method, n_verts=int(mask.sum()), n_pins=int(len(pins)),
            mean_y=float(py.mean()), min_y=float(py.min()), max_y=float(py.max()),
        ))
        all_pins.append(pins)
    pin_idx = np.unique(np.concatenate(all_pins)) if all_pins else np.zeros(0, np.int64)
    return pin_idx.astype(np.int64), info


def closest_point_barycentric(p, a, b, c):
    """Barycentric coordinates (k, 3) of the closest point on triangles (a, b, c) to points p.

    All inputs (k, 3) float64. Region tests after Ericson, Real-Time Collision Detection (2005) 5.1.5.
    """
    ab, ac, ap = b - a, c - a, p - a
    d1 = np.einsum("ij,ij->i", ab, ap)
    d2 = np.einsum("ij,ij->i", ac, ap)
    bp = p - b
    d3 = np.einsum("ij,ij->i", ab, bp)
    d4 = np.einsum("ij,ij->i", ac, bp)
    cp = p - c
    d5 = np.einsum("ij,ij->i", ab, cp)
    d6 = np.einsum("ij,ij->i", ac, cp)
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    out = np.empty((p.shape[0], 3))
    denom = va + vb + vc
    denom = np.where(denom != 0, denom, 1.0)
    out[:, 1] = vb / denom
    out[:, 2] = vc / denom
    out[:, 0] = 1.0 - out[:, 1] - out[:, 2]

    def put(mask, w):
        out[mask] = w[mask] if w.ndim == 2 else w

    with np.errstate(divide="ignore", invalid="ignore"):
        # edge regions (checked before vertex regions, which override them)
        m_bc = (va <= 0) & ((d4 - d3) >= 0) & ((d5 - d6) >= 0)
        t = np.clip((d4 - d3) / ((d4 - d3) + (d5 - d6)), 0, 1)
        put(m_bc, np.stack([np.zeros_like(t), 1 - t, t], 1))
        m_ac = (vb <= 0) & (d2 >= 0) & (d6 <= 0)
        t = np.clip(d2 / (d2 - d6), 0, 1)
        put(m_ac, np.stack([1 - t, np.zeros_like(t), t], 1))
        m_ab = (vc <= 0) & (d1 >= 0) & (d3 <= 0)
        t = np.clip(d1 / (d1 - d3), 0, 1)
        put(m_ab, np.stack([1 - t, t, np.zeros_like(t)], 1))
    put((d6 >= 0) & (d5 <= d6), np.array([0.0, 0.0, 1.0]))
    put((d3 >= 0) & (d4 <= d3), np.array([0.0, 1.0, 0.0]))
    put((d1 <= 0) & (d2 <= 0), np.array([1.0, 0.0, 0.0]))
    return out


def attach_to_body(points, body_verts, body_tris, candidates=16):
    """Nearest body triangle and barycentric coordinates of each point.

    The ``candidates`` triangles with the nearest centroids (cKDTree) are tested exactly.

    Parameters
    ----------
    points : (p, 3) float64, m
    body_verts : (N, 3) float64, m
    body_tris : (T, 3) int64
    candidates : int

    Returns
    -------
    tri_idx : (p,) int64
    bary : (p, 3) float64
        Non-negative, summing to 1.
    """
    from scipy.spatial import cKDTree

    pts = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
    v = np.asarray(body_verts, dtype=np.float64)
    tris = np.asarray(body_tris, dtype=np.int64)
    k = int(min(candidates, len(tris)))
    if len(pts) == 0:
        return np.zeros(0, np.int64), np.zeros((0, 3))
    cent = v[tris].mean(axis=1)
    _, cand = cKDTree(cent).query(pts, k=k)
    cand = cand.reshape(len(pts), k)
    flat = cand.ravel()
    pp = np.repeat(pts, k, axis=0)
    t = tris[flat]
    bary = closest_point_barycentric(pp, v[t[:, 0]], v[t[:, 1]], v[t[:, 2]])
    q = np.einsum("ij,ijk->ik", bary, v[t])
    d2 = np.sum((q - pp) ** 2, axis=1).reshape(len(pts), k)
    best = np.argmin(d2, axis=1)
    rows = np.arange(len(pts)) * k + best
    return cand[np.arange(len(pts)), best].astype(np.int64), bary[rows]


def attached_positions(tri_idx, bary, body_verts, body_tris):
    """Positions (p, 3) m of attached pins on a (possibly morphed) body with the same topology."""
    v = np.asarray(body_verts, dtype=np.float64)
    t = np.asarray(body_tris, dtype=np.int64)[np.asarray(tri_idx, dtype=np.int64)]
    return np.einsum("ij,ijk->ik", np.asarray(bary, dtype=np.float64), v[t])
