"""The body a command works on: MakeHuman's average body, a body file, or one built to measurements.

``resolve_body`` is the one place that turns "which body" (a file, measurement targets, a gender)
into vertices, for ``vfit drape``, ``vfit transfer`` and the drape set-up
(:mod:`vfit_engine.drape.setup`).
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np

from vfit_engine.body.bodyio import read_body
from vfit_engine.body.model import N_BODY, N_VERTS, BodyModel
from vfit_engine.body.morph import Morpher
from vfit_engine.errors import InputError
from vfit_engine.io.mesh import read_mesh
from vfit_engine.units import LENGTH_UNITS


@dataclass
class Body:
    """A body with hm08 topology.

    Attributes
    ----------
    verts : (13380 or 19158, 3) float64, m
        Body vertices first, then (when known) the helper geometry clothes bindings read: a body
        built from measurements or a MakeHuman export has all 19,158; most body files only 13,380.
    description : dict
        Where it came from (``source``: default, file or morph; gender, targets ...), for reports.
    gender : str or float or None
    """

    verts: np.ndarray
    description: dict = field(default_factory=dict)
    gender: object = None

    @property
    def surface(self):
        """(13380, 3) float64, m: the visible body (what cloth collides with)."""
        return np.ascontiguousarray(self.verts[:N_BODY])

    @property
    def has_helpers(self):
        """True when the helper vertices (what .mhclo bindings read) are there."""
        return self.verts.shape[0] == N_VERTS


def default_body(model: BodyModel, gender="female") -> Body:
    """MakeHuman's young-adult average body of ``gender`` (the body MakeHuman clothes are made on)."""
    return Body(model.default_verts(gender), {"source": "default", "gender": gender}, gender)


def read_body_file(path, model: BodyModel, units="auto") -> Body:
    """A body file (hm08 topology, m/dm/cm/mm), with its helper vertices when the file has them."""
    verts, unit = read_body(path, model, units)
    mesh = read_mesh(path)  # read_body keeps the visible body; the helpers serve .mhclo bindings
    if mesh.n_verts == N_VERTS:
        verts = np.ascontiguousarray(mesh.verts * LENGTH_UNITS[unit])
    return Body(verts, {"source": str(path), "units": unit})


def resolve_body(model: BodyModel, path=None, targets=None, weight_kg=None, gender="female", definition="iso") -> Body:
    """The body asked for: a file, else one built to ``targets`` / ``weight_kg``, else the default.

    Parameters
    ----------
    model : BodyModel
    path : str or Path or None
        A body file; excludes ``targets`` and ``weight_kg``.
    targets : dict or None
        Measurement name -> metres (as :meth:`vfit_engine.body.morph.Morpher.solve` takes them).
    weight_kg : float or None
    gender : "female", "male" or float in 0..1
    definition : {"iso", "makehuman", "spline"}

    Raises
    ------
    InputError
        Both a file and measurements, a missing or unreadable file, unreachable targets.
    """
    targets = dict(targets or {})
    if path is not None:
        if targets or weight_kg is not None:
            raise InputError("give either a body file or measurements, not both")
        if not os.path.isfile(path):
            raise InputError(f"body file not found: {path}")
        return read_body_file(path, model)
    if targets or weight_kg is not None:
        res = Morpher(model).solve(targets, gender=gender, definition=definition, weight_kg=weight_kg)
        return Body(res.verts, {"source": "morph", "gender": gender, "definition": definition,
                                "targets_cm": {k: round(v * 100, 4) for k, v in targets.items()},
                                "weight_kg": weight_kg}, gender)
    return default_body(model, gender)
