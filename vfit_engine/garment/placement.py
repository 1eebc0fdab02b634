"""Where a garment starts: on the body it was made for, as its file places it or as its binding does.

A garment file usually sits on the body it was made for (MakeHuman clothes on MakeHuman's average
body of their gender). Some do not: an outfit modelled beside or above the body, a file moved after
it was bound. Draping it where it is would drape it in the air (or over the head), so:

* a garment whose file deviates from its ``.mhclo`` binding's fit on that body by more than
  ``MAX_BINDING_GAP`` on average is placed by its binding (MakeHuman fits clothes the same way);
* a garment without a usable binding must sit on the body: its bounding box must overlap the
  body's and it must rest on the body somewhere -- ``NEAR_SHARE`` of its vertices within
  ``MAX_BODY_GAP`` of a body vertex (a loose skirt or coat touches at its waist or shoulders);
  otherwise it is refused with the distance, since nothing says where it belongs.

The binding's reference distances (``x_scale`` / ``y_scale`` / ``z_scale`` lines: the extent of two
body vertices along an axis on the body the garment was made on) give that body's size, reported
beside the same distances on vfit's bodies (:func:`made_on`).
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from vfit_engine.errors import InputError
from vfit_engine.garment.mhclo import MHCLO_UNIT, evaluate_mhclo
from vfit_engine.units import LENGTH_UNITS

#: Mean distance (m) between a garment file and its binding's fit above which the file is taken to be
#: somewhere else (the MakeHuman suits deviate by 9-17 mm on vfit's average bodies).
MAX_BINDING_GAP = 0.05
#: A garment without a binding rests on the body: at least NEAR_SHARE of its vertices lie within
#: MAX_BODY_GAP (m) of a body vertex (body vertices are ~1 cm apart). Loose: a cape touches only at its
#: shoulders, a tunic with 3.5 cm of ease nowhere closer (both were refused at 10 % within 3 cm).
MAX_BODY_GAP = 0.06
NEAR_SHARE = 0.02


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
        Matching the garment's vertices (:meth:`vfit_engine.garment.garment.Garment.binding`).
    name : str
        For messages (the file name).

    Returns
    -------
    verts : (n, 3) float64, m
    info : dict
        ``placed``: ``file`` (as given) or ``mhclo`` (by the binding); ``file_gap_mm``: mean distance of
        the file from the binding's fit (None without one); ``body_gap_mm``: the distance to the nearest
        body vertex that ``NEAR_SHARE`` of the placed garment's vertices are within.

    Raises
    ------
    InputError
        The garment is away from the body and has no binding to place it with.
    """
    pos = np.ascontiguousarray(garment_verts, dtype=np.float64)
    info = dict(placed="file", file_gap_mm=None)
    if binding is not None and reference.has_helpers:
        fit = evaluate_mhclo(binding, reference.verts)
        gap = float(np.mean(np.linalg.norm(fit - pos, axis=1)))
        info["file_gap_mm"] = 1000.0 * gap
        if gap > MAX_BINDING_GAP:
            pos, info["placed"] = fit, "mhclo"
    body = reference.surface
    near = _near_gap(pos, body)
    info["body_gap_mm"] = 1000.0 * near
    if info["placed"] == "file" and not (_boxes_overlap(pos, body) and near <= MAX_BODY_GAP):
        far = _box_distance(pos, body)
        where = (f"{far:.1f} m from the body (bounding boxes do not overlap)" if far > 0 else
                 f"{100 * near:.1f} cm from the body (its nearest {100 * NEAR_SHARE:.0f} % of vertices)")
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


def _near_gap(points, body):
    """Distance (m) to the nearest body vertex within which NEAR_SHARE of ``points`` lie."""
    if not len(points):
        return 0.0
    d, _ = cKDTree(body).query(points)
    return float(np.quantile(d, NEAR_SHARE))


def _boxes_overlap(a, b):
    return bool(np.all(a.min(0) <= b.max(0)) and np.all(b.min(0) <= a.max(0)))


def _box_distance(a, b):
    """Distance between the two bounding boxes, m (0 when they overlap)."""
    gap = np.maximum(0.0, np.maximum(a.min(0) - b.max(0), b.min(0) - a.max(0)))
    return float(np.linalg.norm(gap))
