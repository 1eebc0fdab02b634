"""Where a garment starts: on the body it was made for, as its file places it or as its binding does.

A garment file usually sits on the body it was made for (MakeHuman clothes on MakeHuman's average
body of their gender). Some do not: an outfit modelled beside or above the body, a file moved after
it was bound. Draping it where it is would drape it in the air (or over the head), so:

* a garment whose file deviates from its ``.mhclo`` binding's fit on that body by more than
  ``MAX_BINDING_GAP`` on average is placed by its binding (MakeHuman fits clothes the same way);
* a garment without a usable binding must sit on the body: its bounding box must overlap the
  body's and the median distance of its vertices to the body's must be at most ``MAX_BODY_GAP``;
  otherwise it is refused with the distance, since nothing says where it belongs.

The binding's reference distances (``x_scale`` / ``y_scale`` / ``z_scale`` lines: the extent of two
body vertices along an axis on the body the garment was made on) give that body's size, reported
beside the same distances on vfit's bodies (:func:`made_on`).
"""
from __future__ import annotations

import numpy as np

from vfit_engine.errors import InputError

#: Mean distance (m) between a garment file and its binding's fit above which the file is taken to be
#: somewhere else (the MakeHuman suits deviate by 9-17 mm on vfit's average bodies).
MAX_BINDING_GAP = 0.05
#: Largest median distance (m) from a garment's vertices to the nearest body vertex for a garment
#: without a binding (clothes lie within a few centimetres of the skin; a long skirt's hem further).
MAX_BODY_GAP = 0.05


def usable_binding(binding, n_verts):
    """The binding if it binds exactly the garment's ``n_verts`` vertices, else None."""
    if binding is None or binding.n_verts != n_verts:
        return None
    return binding


def place_garment(garment_verts, reference, binding=None, name="garment"):
    """The garment's positions on the body it was made for.

    Parameters
    ----------
    garment_verts : (n, 3) float64, m
        As the file gives them.
    reference : Body
        The body the garment was made for (:class:`vfit_engine.body.resolve.Body`; the binding needs its
        helper vertices).
    binding : MhcloBinding or None
        Matching the garment's vertices (:func:`usable_binding`).
    name : str
        For messages (the file name).

    Returns
    -------
    verts : (n, 3) float64, m
    info : dict
        ``placed``: ``file`` (as given) or ``mhclo`` (by the binding); ``file_gap_mm``: mean distance of
        the file from the binding's fit (None without one); ``body_gap_mm``: median distance of the
        placed garment's vertices to the nearest body vertex.

    Raises
    ------
    InputError
        The garment is away from the body and has no binding to place it with.
    """
    from vfit_engine.garment.mhclo import evaluate_mhclo

    pos = np.ascontiguousarray(garment_verts, dtype=np.float64)
    info = dict(placed="file", file_gap_mm=None)
    if binding is not None and reference.has_helpers:
        fit = evaluate_mhclo(binding, reference.verts)
        gap = float(np.mean(np.linalg.norm(fit - pos, axis=1)))
        info["file_gap_mm"] = 1000.0 * gap
        if gap > MAX_BINDING_GAP:
            pos, info["placed"] = fit, "mhclo"
    body = reference.surface
    median = _median_gap(pos, body)
    info["body_gap_mm"] = 1000.0 * median
    if info["placed"] == "file" and not (_boxes_overlap(pos, body) and median <= MAX_BODY_GAP):
        far = _box_distance(pos, body)
        where = (f"{far:.1f} m from the body (bounding boxes do not overlap)" if far > 0 else
                 f"{100 * median:.1f} cm from the body (median distance of its vertices)")
        raise InputError(f"{name} is {where}; it has no .mhclo binding to place it with: "
                         f"move it onto the body it was made for (MakeHuman's average body) or give its .mhclo")
    return pos, info


def made_on(binding, reference, body=None):
    """Size of the body the garment was made on, beside the same measure on vfit's bodies.

    Returns
    -------
    dict or None
        Per axis with a ``*_scale`` line: ``made_on_cm`` (the binding's reference distance),
        ``reference_cm`` (the same two vertices on ``reference``, the body it is placed on) and, with
        ``body``, ``body_cm`` (the body draped on); None without a binding or scale lines.
    """
    from vfit_engine.garment.mhclo import MHCLO_UNIT
    from vfit_engine.units import LENGTH_UNITS

    if binding is None or not binding.scales:
        return None
    out = {}
    for n, ax in enumerate("xyz"):
        if ax not in binding.scales:
            continue
        a, b, ref = binding.scales[ax]
        row = {"made_on_cm": round(100.0 * ref * LENGTH_UNITS[MHCLO_UNIT], 3)}
        for key, bd in (("reference_cm", reference), ("body_cm", body)):
            if bd is not None and bd.verts.shape[0] > max(a, b):
                row[key] = round(100.0 * abs(float(bd.verts[a, n] - bd.verts[b, n])), 3)
        out[ax] = row
    return out


def _median_gap(points, body):
    from scipy.spatial import cKDTree

    if not len(points):
        return 0.0
    d, _ = cKDTree(body).query(points)
    return float(np.median(d))


def _boxes_overlap(a, b):
    return bool(np.all(a.min(0) <= b.max(0)) and np.all(b.min(0) <= a.max(0)))


def _box_distance(a, b):
    """Distance between the two bounding boxes, m (0 when they overlap)."""
    gap = np.maximum(0.0, np.maximum(a.min(0) - b.max(0), b.min(0) - a.max(0)))
    return float(np.linalg.norm(gap))
