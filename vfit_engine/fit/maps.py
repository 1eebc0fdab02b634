"""Fit maps: per-vertex figures of a draped garment (``OUTDIR/fit.ply``).

Every map is one float per garment vertex, in the garment's vertex order:

``strain``        fraction: the largest yarn-edge strain at the vertex against the garment as given
                  (the polygons' own edges; :func:`vfit_engine.drape.metrics.vertex_strain`).
``shear_deg``     degrees: the largest change of a polygon corner angle at the vertex.
``ease_mm``       mm: signed distance from the skin along the body's normal (the closest body point's
                  outward normal; negative: pressed into the body). Beyond ``EASE_REACH`` it is capped.
``pressure_kpa``  kPa: contact pressure of the settled cloth on the body (below); 0 off the body.
``contact``       1 where the cloth rests on the body (``ease_mm`` <= ``CONTACT_MM``), else 0.

Pressure. By Laplace's law a stretched membrane presses on what it is wrapped round with p = T1 k1 + T2 k2:
a tube under hoop tension T round a limb of radius r presses T / r. The tension is the fabric's measured
stretch stiffness times the yarn strain beyond the band the solver leaves free, the curvature the body's
under the cloth, smoothed over a few centimetres (:mod:`vfit_engine.fit.pressure`). For scale, garments
press 0.5-2 kPa, medical compression stockings 1.3-4 kPa and more (``docs/pressure.md``).
"""
from __future__ import annotations

import numpy as np

from vfit_engine.drape.metrics import corner_angles, vertex_strain
from vfit_engine.drape.settings import DrapeSettings
from vfit_engine.fit.pressure import collider_pressure

#: Distance within which a vertex counts as resting on the body, mm (the contact skin is 2-3 mm).
CONTACT_MM = 5.0
#: ``ease_mm`` is exact up to this distance from the body, m; farther cloth reads this value.
EASE_REACH = 0.5
#: The maps in ``fit.ply``'s vertex properties, in order.
MAP_NAMES = ("strain", "shear_deg", "ease_mm", "pressure_kpa", "contact")
#: Units of the maps (``report.json`` and the PLY header's comments say them).
MAP_UNITS = {"strain": "fraction", "shear_deg": "deg", "ease_mm": "mm", "pressure_kpa": "kPa", "contact": "0/1"}


def vertex_shear_deg(mesh, pos):
    """(n,) float64, deg: the largest change of a polygon corner angle at each vertex."""
    d = np.degrees(np.abs(corner_angles(pos, mesh.face_verts, mesh.face_offsets)
                          - corner_angles(mesh.verts, mesh.face_verts, mesh.face_offsets)))
    out = np.zeros(mesh.n_verts)
    np.maximum.at(out, mesh.face_verts, d)
    return out


def fit_maps(setup, pos, slack=None):
    """All the maps (module docstring) of a drape of ``setup`` (:class:`vfit_engine.drape.DrapeSetup`)
    ending at ``pos`` (n, 3) m: dict name -> (n,) float64, in :data:`MAP_NAMES` order. ``slack``: the strain
    the solver left free (default: the drape's, ``DrapeSettings().solver.slack``)."""
    pos = np.ascontiguousarray(pos, dtype=np.float64)
    mesh = setup.garment.mesh
    query = setup.collider.query(pos, max_out=EASE_REACH, max_in=EASE_REACH)
    d = np.clip(query[0], -EASE_REACH, EASE_REACH)  # +-inf beyond the exact range
    ease = 1000.0 * d
    contact = ease <= CONTACT_MM
    slack = DrapeSettings().solver.slack if slack is None else slack
    pressure = collider_pressure(mesh, pos, setup.material, setup.collider, query, contact & (query[3] >= 0), slack)
    return dict(strain=vertex_strain(mesh, pos), shear_deg=vertex_shear_deg(mesh, pos), ease_mm=ease,
                pressure_kpa=pressure, contact=contact.astype(np.float64))
