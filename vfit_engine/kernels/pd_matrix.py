"""Numba kernels: the projective-dynamics matrix re-weighed by which bands act (``PDSettings.band_weight``).

A yarn inside its free band has no stiffness; at its full weight in the matrix it holds the cloth where the
iterate is (:mod:`vfit_engine.sim.solver_pd`). The solver weighs each band by whether it acts at the step's start
and refactors when that set changes: :func:`acting_bands` finds the set, :func:`band_matrix` writes the matrix's
values into the factor's value array (the pattern is fixed, so the positions of every element's entries are found
once). Both were NumPy (a norm over every pair, two bincounts and ``np.add.at``): 3.6 ms a step on a 2.2 k-vertex
suit, as much as the numeric refactor itself. The pairs' stiffness damping (``PDSettings.stiffness_damping``)
rides on the same entries: :func:`band_matrix` adds its weight, :func:`add_damping_target` its right-hand side.
"""
import math

from vfit_engine._jit import njit


@njit
def acting_bands(x, pi, pj, lo, hi, band, active):
    """Mark in ``active`` (E,) bool the pair elements that act at ``x``: every element that is not a band, and
    the bands at an end of theirs (within 0.2 %). Returns True when the set changed."""
    changed = False
    for e in range(pi.shape[0]):
        act = True
        if band[e]:
            i, j = pi[e], pj[e]
            dx, dy, dz = x[j, 0] - x[i, 0], x[j, 1] - x[i, 1], x[j, 2] - x[i, 2]
            length = math.sqrt(dx * dx + dy * dy + dz * dz)
            act = length <= lo[e] * 1.002 or length >= hi[e] * 0.998
        if act != active[e]:
            changed = True
            active[e] = act
    return changed


@njit
def band_matrix(pi, pj, w, active, share, free, base, w_c, at_ij, at_ji, at_d, data, e_w, pin_w, pair_of, dw):
    """The matrix's values into ``data`` (the factor's value array) with the bands that do not act at ``share``
    of their weight ``w``, and each pair's damping weight ``dw`` (:func:`add_damping_target`) on top; the step's
    element weights ``e_w`` (the first elements' weights, without damping) and the pins' couplings ``pin_w``
    (weights of the pairs ``pair_of``, with it) follow.

    ``base`` (n,) is each free vertex's diagonal outside the pair elements (``m / h^2`` and the forces' diagonal),
    ``w_c`` (n,) its contact weight; a pinned vertex's row is the identity. ``at_ij``, ``at_ji`` (E,) are the
    positions of the element's two off-diagonal entries in ``data`` (-1 where an end is pinned), ``at_d`` (n,)
    those of the diagonal."""
    for q in range(data.shape[0]):
        data[q] = 0.0
    for v in range(free.shape[0]):
        data[at_d[v]] = base[v] + w_c[v] if free[v] else 1.0
    for e in range(pi.shape[0]):
        we = w[e] if active[e] else share * w[e]
        wm = we + dw[e]
        if free[pi[e]]:
            data[at_d[pi[e]]] += wm
        if free[pj[e]]:
            data[at_d[pj[e]]] += wm
        if at_ij[e] >= 0:
            data[at_ij[e]] -= wm
            data[at_ji[e]] -= wm
        if e < e_w.shape[0]:
            e_w[e] = we
    for q in range(pair_of.shape[0]):
        e = pair_of[q]
        pin_w[q] = (w[e] if active[e] else share * w[e]) + dw[e]


@njit
def add_damping_target(y, xp, pi, pj, dw, mh2):
    """Stiffness-proportional damping (``PDSettings.stiffness_damping``), in place: the pair elements' damping
    force ``-dw (u - u_n)`` (``u`` an element's end-to-end vector now, ``u_n`` at the step's start ``xp``) is
    implicit, ``dw`` on the matrix (:func:`band_matrix`) and ``dw u_n`` on the right-hand side; the latter enters
    through the step's prediction ``y`` (n, 3), which the right-hand side weighs by ``mh2`` (``m / h^2``, 0 at
    pins: their rows are the identity)."""
    for e in range(pi.shape[0]):
        if dw[e] == 0.0:
            continue
        i, j = pi[e], pj[e]
        for c in range(3):
            f = dw[e] * (xp[i, c] - xp[j, c])
            if mh2[i] > 0.0:
                y[i, c] += f / mh2[i]
            if mh2[j] > 0.0:
                y[j, c] -= f / mh2[j]
