"""Automatic pin selection for garments and attachment of pins to the body surface.

A pinned garment vertex follows a fixed point of the body surface (a triangle and barycentric
coordinates) instead of being simulated; that is what holds trousers up and a top on the shoulders.

Pins per piece (``auto_pins``), at the body levels of :func:`vfit_engine.body.levels.body_levels`:

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
from scipy.spatial import cKDTree

from vfit_engine.body.levels import Sections, body_center_xz, body_levels
from vfit_engine.errors import InputError
from vfit_engine.garment.garment import piece_labels
from vfit_engine.geometry import boundary_loops, closest_point_barycentric, vertex_normals, winding_number

#: Smallest Y component of the body normal counted as "facing up" in the shoulder region.
SHOULDER_MIN_NORMAL_Y = 0.7
#: Largest garment-to-body distance of a shoulder pin, m.
SHOULDER_MAX_DIST = 0.04
#: A piece reaching this far above the armpit level is a top, m.
TOP_MARGIN = 0.02


def _waist_loop(mesh, mask, surf, sec, x_c):
    """Highest boundary loop of the piece that winds around the body centre line, or None."""
    best = None
    for loop in boundary_loops(mesh, mask):
        if len(loop) < 3:
            continue
        p = mesh.verts[loop]
        y = float(p[:, 1].mean())
        w = winding_number(p[:, [0, 2]], body_center_xz(surf, sec, x_c, y))
        if abs(w) > 0.5 and (best is None or y > best[1]):
            best = (loop, y)
    return best


def _shoulder_pins(mesh, mask, v, surf_idx, normals, levels):
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

    v = np.asarray(body_verts, dtype=np.float64)
    tris = np.asarray(body_tris, dtype=np.int64)
    surf_idx = np.unique(tris)
    surf = v[surf_idx]
    sec = Sections(v, tris)
    levels = body_levels(v, tris, sections=sec)
    normals = vertex_normals(v, tris, outward=True)
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


def read_pin_file(path, vertex_count):
    """Garment vertex indices (0-based, one per line; blank lines and ``#`` comments skipped).

    Raises
    ------
    InputError
        Unreadable file, a line that is not an integer, an index outside ``0..vertex_count-1``, or no
        index at all.
    """
    try:
        with open(path, encoding="utf-8-sig") as f:
            lines = f.read().splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read pin file {path}: {getattr(exc, 'strerror', None) or exc}") from None
    out = []
    for no, line in enumerate(lines, 1):
        text = line.split("#", 1)[0].strip()
        if not text:
            continue
        try:
            value = int(text)
        except ValueError:
            raise InputError(f"pin file {path}, line {no}: {text!r} is not a vertex index") from None
        if not 0 <= value < vertex_count:
            raise InputError(f"pin file {path}, line {no}: vertex {value} does not exist "
                             f"(garment has {vertex_count})")
        out.append(value)
    if not out:
        raise InputError(f"pin file {path} lists no vertex: give garment vertex indices (0-based, one per line) "
                         "or use --pin none")
    return np.unique(np.array(out, dtype=np.int64))
