"""The Cusick drape test (BS 5058, ISO 9073-9) on the cloth solver.

A disc of fabric 30 cm across, clamped between two discs 18 cm across, hangs in folds under its own
weight. Seen from above, its shadow ``S`` gives the drape coefficient::

    DC = (S - Sd) / (Sf - Sd)          (Sd the support's area, Sf the specimen's)

low for a fabric that falls in soft folds (silk 0.2-0.4), high for a stiff one (denim 0.7-0.9); the folds
round the rim are its nodes (5-8 typically).

Here the specimen is meshed as garments are, in quads (:func:`vfit_engine.textile.specimen.annulus`: the
ring outside the support, and one ring of quads under its rim, all pinned), so the test runs the drape's
own cloth: hinges for bending, stretch constraints, the corners' shear limit and shear springs. Each free
vertex is turned round the centre by up to a tenth of the spacing (seeded): a perfect polar grid would
fold with its own symmetry, a real fabric folds with its unevenness. It falls from flat in
:class:`vfit_engine.sim.solver_verlet.SolverVerlet` (or the projective solver,
:func:`vfit_engine.textile.settle.specimen_solver`, at :data:`PD_STEP`) until still. ``S`` is the union of the
cloth's triangles and the support's disc projected on the horizontal plane (rasterised, 0.5 mm pixels), ``Sf``
and ``Sd`` the flat mesh's outer and inner rims' areas (polygons a little inside their circles). Nodes are the
maxima of the shadow's outline ``r(phi)`` that stand out by more than 5 mm, and a quarter of its depth, from the
troughs beside them. (A triangle mesh with stretch constraints on every edge has no shear model: its
triangles only shear by shrinking in the free compression band, and it drapes 10-15 points lower.)
"""
from __future__ import annotations

import math
import time

import numpy as np
from scipy.signal import find_peaks

from vfit_engine.kernels.raster import rasterize
from vfit_engine.sim.model import Model
from vfit_engine.sim.solver_verlet import VerletSettings
from vfit_engine.textile.settle import fall_still, specimen_solver
from vfit_engine.textile.specimen import annulus

#: The specimen's and the support's radii, m (BS 5058: 30 and 18 cm).
RADIUS = 0.15
SUPPORT = 0.09
#: The projective solver's step in the test, s (at 1/240 s silk and cotton were still moving after 8 s, at this step
#: they settle in 3-5 s, their coefficients within 0.01 of 1/240 s's).
PD_STEP = 1.0 / 960.0
#: Shadow raster pixel, m; a node's prominence, m.
PIXEL = 0.0005
PROMINENCE = 0.005


def specimen_model(material, edge, seed=0):
    """The specimen meshed at ``edge`` (m) and pinned on the support (module docstring).

    Returns
    -------
    model : Model
    tris : (m, 3) int64
        Triangles covering the specimen as seen from above (the support's disc included).
    flat_m2, support_m2 : float
        The flat specimen's and the support's areas as meshed.
    """
    rng = np.random.default_rng(seed)
    pos, fv, fo, ring = annulus(SUPPORT, RADIUS, edge)
    free = ring >= 2
    # each free vertex moved round the ring by up to a tenth of the spacing (seeded): a perfect polar grid
    # would fold with the symmetry of its quad count, a real fabric with its own unevenness
    turn = rng.uniform(-0.1, 0.1, free.sum()) * edge / np.hypot(pos[free, 0], pos[free, 2])
    c, s_ = np.cos(turn), np.sin(turn)
    pos[free, 0], pos[free, 2] = c * pos[free, 0] - s_ * pos[free, 2], s_ * pos[free, 0] + c * pos[free, 2]
    quads = fv.reshape(-1, 4)
    n_a = int(np.count_nonzero(ring == 0))
    inner = np.flatnonzero(ring == 1)
    outer = np.flatnonzero(ring == ring.max())
    centre = pos.shape[0]
    fan = np.stack([np.full(n_a, centre), inner, np.roll(inner, -1)], axis=1)
    tris = np.r_[quads[:, [0, 1, 2]], quads[:, [0, 2, 3]], fan]
    model = Model.from_polygons(fv, fo, pos, material, pin_indices=np.flatnonzero(ring <= 1))
    return model, tris, _polygon_area(pos[outer]), _polygon_area(pos[inner])


def _polygon_area(ring):
    x, z = ring[:, 0], ring[:, 2]
    return float(0.5 * abs(np.dot(x, np.roll(z, -1)) - np.dot(z, np.roll(x, -1))))


def shadow_area(pos, tris, pixel=PIXEL):
    """Area (m^2) of the union of the triangles ``tris`` (m, 3) at ``pos`` (n, 3) seen from above (along y)."""
    xz = pos[:, [0, 2]]
    lo = xz.min(axis=0) - 2 * pixel
    size = np.ceil((xz.max(axis=0) + 2 * pixel - lo) / pixel).astype(int)
    xyz = np.ascontiguousarray(np.c_[(xz - lo) / pixel, pos[:, 1]])
    image = np.zeros((size[1], size[0], 3))
    depth = np.full((size[1], size[0]), -np.inf)
    rasterize(xyz, np.ascontiguousarray(tris, dtype=np.int64), np.ones((pos.shape[0], 3)),
              np.ones(tris.shape[0]), image, depth)
    return float(np.count_nonzero(np.isfinite(depth))) * pixel * pixel


def outline(pos, bins=360):
    """(bins,) float64, m: the largest horizontal radius of the cloth in each direction round the centre,
    smoothed over 5 degrees (the vertices' spacing leaves the raw maxima ragged)."""
    r = np.hypot(pos[:, 0], pos[:, 2])
    phi = np.arctan2(pos[:, 2], pos[:, 0])
    b = ((phi + math.pi) / (2 * math.pi) * bins).astype(int) % bins
    out = np.zeros(bins)
    np.maximum.at(out, b, r)
    while np.any(out == 0):  # bins no vertex fell in take their neighbours' value
        out = np.where(out == 0, np.maximum(np.roll(out, 1), np.roll(out, -1)), out)
    w = max(1, int(round(bins * 5 / 360)))
    return np.convolve(np.r_[out[-w:], out, out[:w]], np.ones(2 * w + 1) / (2 * w + 1), mode="same")[w:-w]


def count_nodes(r, prominence=PROMINENCE):
    """Folds round the rim: circular maxima of the outline ``r`` (bins,) standing ``prominence`` (m), and a
    quarter of the outline's depth, above the troughs either side (a fold's shoulder is not a fold)."""
    n = r.size
    prominence = max(prominence, 0.25 * float(r.max() - r.min()))
    peaks, _ = find_peaks(np.r_[r, r, r], prominence=prominence)
    return int(np.count_nonzero((peaks >= n) & (peaks < 2 * n)))


def drape_test(material, edge=0.01, seed=0, max_time=8.0, still=5e-4, air_damping=8.0, settings=None, dt=None,
               solver="verlet"):
    """The Cusick test of ``material`` meshed at ``edge`` (m) (module docstring), at the step ``dt`` (s; default the
    largest at which every hinge is explicit, at most 1/240 s; for ``solver`` "pd" :data:`PD_STEP`).

    Returns
    -------
    dict
        ``drape_coefficient`` (fraction), ``nodes``, ``shadow_m2``, ``specimen_m2``, ``support_m2``,
        ``edge_m``, ``vertices``, ``dt_s``, ``sim_time_s``, ``settled``, ``softened_hinges``, ``time_s``;
        ``pos`` (n + 1, 3) m and ``tris`` (m, 3): the draped specimen and the support's centre, triangles
        covering both.
    """
    t0 = time.perf_counter()
    model, tris, flat, sd = specimen_model(material, edge, seed)
    if solver == "pd" and dt is None:
        dt = PD_STEP
    solver = specimen_solver(model, solver, settings or VerletSettings(air_damping=air_damping))
    state, dt, t, settled = fall_still(solver, 1.0 / 240.0, max_time, still, calm=10, after=0.5, dt=dt)
    pos = np.r_[state.pos, [[0.0, 0.0, 0.0]]]  # the support's centre: the fan of tris covering it
    s = shadow_area(pos, tris)
    return dict(drape_coefficient=(s - sd) / (flat - sd), nodes=count_nodes(outline(pos)), shadow_m2=s,
                specimen_m2=flat, support_m2=sd, edge_m=edge, vertices=model.particle_count, dt_s=dt, sim_time_s=t,
                settled=settled, softened_hinges=solver.softened_hinges, time_s=time.perf_counter() - t0,
                pos=pos.copy(), tris=tris)
