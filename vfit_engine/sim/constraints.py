"""The cloth's constraints as :class:`vfit_engine.sim.solver_verlet.SolverVerlet` sweeps them, built from a
:class:`~vfit_engine.sim.model.Model` and its :class:`~vfit_engine.sim.solver_settings.VerletSettings`:

* *stretch*: every polygon edge free within a band (``1 - compression`` to ``1 + slack`` of its rest length),
  beyond it with the fabric's stretch stiffness (compliance ``1 / k``);
* *bend limit*: every second-neighbour pair may shorten freely but lengthens beyond ``1 + bend_limit`` only
  against a compliance :data:`BEND_LIMIT_SOFTNESS` times the fabric's stretch;
* *shear limit*: every polygon corner keeps its angle within ``shear_limit_deg`` of the garment's;
* *shear springs*: each polygon diagonal pulls its quad back to shape, relaxed by ``shear_restore``.

The solver orders the arrays (sweep order, segments) and owns them; the kernel's equations are in
:mod:`vfit_engine.kernels.cloth`.
"""
from __future__ import annotations

import math

import numpy as np

from vfit_engine.sim.springs import BEND, SHEAR, STRUCTURAL

#: Relaxation weights: stiffness / (this percentile of the family's stiffnesses), clipped to
#: [RELAX_MIN, 1] (a few very stiff constraints must not make the rest converge slowly).
RELAX_PERCENTILE = 90.0
RELAX_MIN = 0.1
#: Beyond its limit a bend pair resists as a yarn this many times softer than the fabric's stretch
#: (compliant, not rigid): folds modelled into the garment still hold (nothing but the weak bending
#: springs resists their opening otherwise), while where the body forces the cloth wider the pairs
#: stretch with it instead of a rigid limit fighting the body's push (a top made tight over a bust
#: jittered at the underbust and never settled).
BEND_LIMIT_SOFTNESS = 10.0


def corner_angle(pos, ends, corner):
    """(k,) float64, radians: the angle at ``corner`` (k,) between ``ends`` (k, 2)."""
    u = pos[ends[:, 0]] - pos[corner]
    w = pos[ends[:, 1]] - pos[corner]
    return np.arctan2(np.linalg.norm(np.cross(u, w), axis=1), np.einsum("ij,ij->i", u, w))


#: Constraint kinds (``SolverVerlet._c_kind``).
KIND_STRETCH, KIND_BEND, KIND_ANGLE, KIND_SHEAR = 0, 1, 2, 3
#: The solver's per-constraint arrays, all in sweep order.
CONSTRAINT_ARRAYS = ("_c_i", "_c_j", "_c_corner", "_c_lo", "_c_hi", "_t_lo", "_t_hi", "_c_alpha", "_c_relax",
                     "_c_kind", "_c_rest")


def build_constraints(m, st):
    """The constraints of model ``m`` (:class:`vfit_engine.sim.model.Model`) under settings ``st``
    (:class:`VerletSettings`): stretch (structural springs), bend limits, shear limits (corner angles) and the
    compliant shear springs that restore the corners' angles; a dict of :data:`CONSTRAINT_ARRAYS`, each
    (C,) and contiguous, in the model's order by kind."""
    parts = [_distance_constraints(m, st, np.flatnonzero((m.spring_type == STRUCTURAL) & (m.spring_k > 0)),
                                   KIND_STRETCH)]
    if st.bend_limit is not None:
        parts.append(_distance_constraints(m, st, np.flatnonzero(m.spring_type == BEND), KIND_BEND))
    if st.shear_limit_deg is not None and m.corners.size:
        parts.append(_angle_constraints(m, st))
        if st.shear_restore > 0:
            parts.append(_distance_constraints(m, st, np.flatnonzero((m.spring_type == SHEAR) & (m.spring_k > 0)),
                                               KIND_SHEAR))
    return {name: np.ascontiguousarray(np.concatenate([p[name] for p in parts])) for name in CONSTRAINT_ARRAYS}

def _distance_constraints(m, st, springs, kind):
    """Constraint arrays (a dict) of the model springs ``springs`` of one ``kind``."""
    rest = m.spring_rest[springs]
    k = m.spring_k[springs]
    lo, hi, alpha, relax = np.zeros(springs.size), rest.copy(), np.zeros(springs.size), np.ones(springs.size)
    if kind == KIND_STRETCH:
        lo, hi, alpha = rest * (1.0 - st.compression), rest * (1.0 + st.slack), 1.0 / k
    elif kind == KIND_BEND:
        hi = rest * (1.0 + st.bend_limit)  # shortening (folding) is free, unfolding limited
        alpha = BEND_LIMIT_SOFTNESS * rest / stretch_rigidity(m)
    else:  # a shear spring pulling its quad back to shape, weighted lightly where it conflicts
        # a band of width 0 (a spring both ways): with lo = 0 it could only pull its long diagonal
        # in, which the quad satisfies by shrinking inside the stretch's free compression band
        # while staying sheared (a quad sheared 8 degrees stalled at 3.7, its edges 3.7 % short)
        lo, alpha, relax = rest.copy(), 1.0 / k, np.full(springs.size, st.shear_restore)
    if st.relax_by_stiffness and kind == KIND_STRETCH and springs.size:
        # Gauss-Seidel settles a conflict where sum relax_e C_e u_e = 0 at every vertex: relax
        # proportional to the stiffness makes that the elastic balance sum k_e C_e u_e = 0
        relax = np.clip(k / np.percentile(k, RELAX_PERCENTILE), RELAX_MIN, 1.0)
    n = springs.size
    return dict(_c_i=m.spring_indices[springs, 0], _c_j=m.spring_indices[springs, 1],
                _c_corner=np.full(n, -1, np.int64), _c_lo=lo, _c_hi=hi, _t_lo=np.zeros(n), _t_hi=np.zeros(n),
                _c_alpha=alpha, _c_relax=relax, _c_kind=np.full(n, kind, np.int64), _c_rest=rest)

def stretch_rigidity(m):
    """The fabric's typical stretch rigidity k l (N) in model ``m``: the median over its structural springs."""
    sel = (m.spring_type == STRUCTURAL) & (m.spring_k > 0)
    return float(np.median(m.spring_k[sel] * m.spring_rest[sel])) if np.any(sel) else math.inf

def _angle_constraints(m, st):
    """Constraint arrays of the polygon corners: each angle within shear_limit_deg of its rest."""
    c = m.corners
    n = c.shape[0]
    angle = corner_angle(m.rest_pos, c[:, [0, 2]], c[:, 1])
    lim = math.radians(st.shear_limit_deg)
    z = np.zeros(n)
    return dict(_c_i=c[:, 0], _c_j=c[:, 2], _c_corner=c[:, 1], _c_lo=z, _c_hi=z,
                _t_lo=np.maximum(angle - lim, 0.0), _t_hi=np.minimum(angle + lim, math.pi), _c_alpha=z,
                _c_relax=np.ones(n), _c_kind=np.full(n, KIND_ANGLE, np.int64), _c_rest=angle)
