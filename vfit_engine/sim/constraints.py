"""The cloth's constraints as :class:`vfit_engine.sim.solver_verlet.SolverVerlet` sweeps them, built from a
:class:`~vfit_engine.sim.model.Model` and its :class:`~vfit_engine.sim.solver_settings.VerletSettings`:

* *stretch*: every polygon edge free within a band (``1 - compression`` to ``1 + slack`` of its rest length),
  beyond it with the fabric's stretch stiffness (compliance ``1 / k``);
* *bend limit*: every second-neighbour pair may shorten freely but lengthens beyond ``1 + bend_limit`` only
  against a compliance :data:`BEND_LIMIT_SOFTNESS` times the fabric's stretch;
* *shear limit*: every polygon corner keeps its angle within ``shear_limit_deg`` of the garment's;
* *shear springs*: each polygon diagonal pulls its quad back to shape, relaxed by ``shear_restore``.

The solver owns one :class:`Constraints` and changes it only through its methods (the sweep order, the bands
it opens); the kernel's equations are in :mod:`vfit_engine.kernels.cloth`.
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


#: Constraint kinds (:attr:`Constraints.kind`).
KIND_STRETCH, KIND_BEND, KIND_ANGLE, KIND_SHEAR = 0, 1, 2, 3


class Constraints:
    """The cloth's constraints, one entry per constraint, every array (C,) and contiguous, in sweep order.

    The solver holds one and reorders or widens it only through its methods.

    Attributes
    ----------
    i, j : (C,) int64
        The two ends (model vertex numbers; an angle constraint's two arms).
    corner : (C,) int64
        An angle constraint's corner vertex; -1 for distance constraints.
    lo, hi : (C,) float64, m
        A distance constraint's free band of lengths (0 for angle constraints).
    t_lo, t_hi : (C,) float64, radians
        An angle constraint's free band of angles (0 for distance constraints).
    alpha : (C,) float64, m/N
        Compliance beyond the band (0: rigid).
    relax : (C,) float64
        Relaxation weight in (0, 1].
    kind : (C,) int64
        ``KIND_STRETCH``, ``KIND_BEND``, ``KIND_ANGLE`` or ``KIND_SHEAR``.
    rest : (C,) float64
        Rest length (m) or rest angle (radians).
    """

    #: The per-constraint arrays, in the order the fields are listed above.
    FIELDS = ("i", "j", "corner", "lo", "hi", "t_lo", "t_hi", "alpha", "relax", "kind", "rest")

    def __init__(self, i, j, corner, lo, hi, t_lo, t_hi, alpha, relax, kind, rest):
        self.i, self.j, self.corner = i, j, corner
        self.lo, self.hi, self.t_lo, self.t_hi = lo, hi, t_lo, t_hi
        self.alpha, self.relax, self.kind, self.rest = alpha, relax, kind, rest

    @property
    def count(self):
        """Number of constraints C."""
        return int(self.i.size)

    def reorder(self, order):
        """Put the constraints in ``order`` (C,) int64 (a permutation), every array contiguous again."""
        for name in self.FIELDS:
            setattr(self, name, np.ascontiguousarray(getattr(self, name)[order]))

    def open_bands(self, inside, strain):
        """Let the constraints with both ends in ``inside`` (n,) bool stretch freely up to ``strain`` (fraction):
        stretch and bend limits open by ``strain``, corner angles by ``strain`` radians."""
        both = inside[self.i] & inside[self.j]
        dist = both & ((self.kind == KIND_STRETCH) | (self.kind == KIND_BEND))
        self.hi[dist] = np.maximum(self.hi[dist], self.rest[dist] * (1.0 + float(strain)))
        ang = both & (self.kind == KIND_ANGLE)
        self.t_lo[ang] = np.maximum(self.t_lo[ang] - float(strain), 0.0)
        self.t_hi[ang] = np.minimum(self.t_hi[ang] + float(strain), math.pi)

    def admit(self, pos, inside):
        """Widen the bands of the constraints with both ends in ``inside`` (n,) bool to admit their lengths and
        angles at ``pos`` (n, 3) m (shear springs keep theirs: they pull the quad back to shape)."""
        both = inside[self.i] & inside[self.j]
        dist = both & (self.kind != KIND_ANGLE) & (self.kind != KIND_SHEAR)
        length = np.linalg.norm(pos[self.j[dist]] - pos[self.i[dist]], axis=1)
        self.hi[dist] = np.maximum(self.hi[dist], length)
        self.lo[dist] = np.minimum(self.lo[dist], length)
        ang = both & (self.kind == KIND_ANGLE)
        angle = corner_angle(pos, np.stack([self.i[ang], self.j[ang]], axis=1), self.corner[ang])
        self.t_lo[ang] = np.minimum(self.t_lo[ang], angle)
        self.t_hi[ang] = np.maximum(self.t_hi[ang], angle)


def build_constraints(m, st):
    """The constraints of model ``m`` (:class:`vfit_engine.sim.model.Model`) under settings ``st``
    (:class:`VerletSettings`): stretch (structural springs), bend limits, shear limits (corner angles) and the
    compliant shear springs that restore the corners' angles; a :class:`Constraints`, in the model's order by
    kind."""
    parts = [_distance_constraints(m, st, np.flatnonzero((m.spring_type == STRUCTURAL) & (m.spring_k > 0)),
                                   KIND_STRETCH)]
    if st.bend_limit is not None:
        parts.append(_distance_constraints(m, st, np.flatnonzero(m.spring_type == BEND), KIND_BEND))
    if st.shear_limit_deg is not None and m.corners.size:
        parts.append(_angle_constraints(m, st))
        if st.shear_restore > 0:
            parts.append(_distance_constraints(m, st, np.flatnonzero((m.spring_type == SHEAR) & (m.spring_k > 0)),
                                               KIND_SHEAR))
    return Constraints(**{name: np.ascontiguousarray(np.concatenate([p[name] for p in parts]))
                          for name in Constraints.FIELDS})

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
    return dict(i=m.spring_indices[springs, 0], j=m.spring_indices[springs, 1],
                corner=np.full(n, -1, np.int64), lo=lo, hi=hi, t_lo=np.zeros(n), t_hi=np.zeros(n),
                alpha=alpha, relax=relax, kind=np.full(n, kind, np.int64), rest=rest)

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
    return dict(i=c[:, 0], j=c[:, 2], corner=c[:, 1], lo=z, hi=z,
                t_lo=np.maximum(angle - lim, 0.0), t_hi=np.minimum(angle + lim, math.pi), alpha=z,
                relax=np.ones(n), kind=np.full(n, KIND_ANGLE, np.int64), rest=angle)
