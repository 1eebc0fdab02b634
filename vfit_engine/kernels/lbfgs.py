"""Numba kernels: quasi-Newton (L-BFGS) iterations of projective dynamics (Liu, Bouaziz & Kavan 2017).

A projective-dynamics step minimises ``E(x) = |x - y|^2_M / (2 h^2) + sum_e w_e |S_e x - p_e|^2 / 2 + ...``; its
gradient at an iterate is ``A x - b(x)`` (``A`` the prefactored matrix, ``b`` the local step's right-hand side,
:func:`vfit_engine.kernels.pd.pd_rhs`), and the plain iteration ``x <- A^-1 b(x)`` is the step ``x - A^-1 grad``.
The matrix has no directions: a pair element resists a turn of its two ends as it resists a stretch, so the turning
modes (a hinge, a sleeve swinging from the shoulder) converge at ``~(m / h^2 + bending) / stiffness`` an iteration,
1e-4 in cotton at 1/120 s. L-BFGS keeps the last ``m`` moves ``s`` and gradient changes ``t`` and moves by
``-H grad``, ``H`` the inverse Hessian they imply on top of ``A^-1`` (the two-loop recursion: :func:`first_loop`, one
solve with ``A``, :func:`second_loop`): it learns those modes' stiffness from the iterates.

The line search (:meth:`vfit_engine.sim.solver_pd.SolverPD._iterate_qn`) takes the energy from the kernels that
build ``b``: :func:`~vfit_engine.kernels.pd.pd_rhs` and :func:`~vfit_engine.kernels.pd.contact_friction` return
theirs, :func:`uzawa_energy` and :func:`pair_energy` give the contact forces' and the stiffness damping's.

Vectors are (n, 3) arrays, their dot products over all 3 n entries (a pinned vertex's gradient and moves are 0).
The history is a ring of ``m`` slots: ``S``, ``T`` (m, n, 3), ``rho`` (m,) ``1 / (s . t)``; ``newest`` the slot
written last and ``count`` how many hold a pair.
"""
from vfit_engine._jit import njit


@njit
def dot3(a, b):
    """``sum(a * b)`` of two (n, 3) arrays."""
    s = 0.0
    for i in range(a.shape[0]):
        s += a[i, 0] * b[i, 0] + a[i, 1] * b[i, 1] + a[i, 2] * b[i, 2]
    return s


@njit
def gradient(indptr, indices, data, x, b, lam, nrm, g, g0):
    """``g = A x - b`` (n, 3) with ``A`` symmetric in CSC (``indptr``, ``indices``, ``data``: all its entries,
    both triangles), and ``g0 = g + lam nrm``: the gradient less the contact forces' (Uzawa's ``lam`` (n,) N along
    ``nrm`` (n, 3)), which change between iterations by their own update, not by the move; the curvature pairs are
    taken from ``g0``."""
    n = x.shape[0]
    for i in range(n):
        g[i, 0] = -b[i, 0]
        g[i, 1] = -b[i, 1]
        g[i, 2] = -b[i, 2]
    for col in range(n):
        x0, x1, x2 = x[col, 0], x[col, 1], x[col, 2]
        for q in range(indptr[col], indptr[col + 1]):
            r = indices[q]
            a = data[q]
            g[r, 0] += a * x0
            g[r, 1] += a * x1
            g[r, 2] += a * x2
    for i in range(n):
        lm = lam[i] if lam[i] > 0.0 else 0.0
        g0[i, 0] = g[i, 0] + lm * nrm[i, 0]
        g0[i, 1] = g[i, 1] + lm * nrm[i, 1]
        g0[i, 2] = g[i, 2] + lm * nrm[i, 2]


@njit
def push_pair(x, x_old, g0, g0_old, S, T, rho, newest, count):
    """Store the pair ``s = x - x_old``, ``t = g0 - g0_old`` in the slot after ``newest`` if its curvature
    ``s . t`` is positive (else the pair is dropped: the energy is not convex along ``s``, and the update needs
    ``s . t > 0`` to stay positive definite). Returns ``(newest, count)``."""
    n = x.shape[0]
    st = ss = tt = 0.0
    for i in range(n):
        for c in range(3):
            s = x[i, c] - x_old[i, c]
            t = g0[i, c] - g0_old[i, c]
            st += s * t
            ss += s * s
            tt += t * t
    # relative to |s| |t|: a pair with next to no curvature would make 1 / (s . t) huge
    if not st > 1e-10 * (ss * tt) ** 0.5:
        return newest, count
    m = S.shape[0]
    k = (newest + 1) % m
    for i in range(n):
        for c in range(3):
            S[k, i, c] = x[i, c] - x_old[i, c]
            T[k, i, c] = g0[i, c] - g0_old[i, c]
    rho[k] = 1.0 / st
    return k, min(count + 1, m)


@njit
def first_loop(q, S, T, rho, alpha, newest, count):
    """The two-loop recursion's first half, newest pair first, on ``q`` (n, 3) in place; ``alpha`` (m,) out."""
    m = S.shape[0]
    for j in range(count):
        k = (newest - j) % m
        a = 0.0
        for i in range(q.shape[0]):
            a += S[k, i, 0] * q[i, 0] + S[k, i, 1] * q[i, 1] + S[k, i, 2] * q[i, 2]
        a *= rho[k]
        alpha[k] = a
        for i in range(q.shape[0]):
            q[i, 0] -= a * T[k, i, 0]
            q[i, 1] -= a * T[k, i, 1]
            q[i, 2] -= a * T[k, i, 2]


@njit
def second_loop(r, S, T, rho, alpha, newest, count):
    """The second half, oldest pair first, on ``r`` (n, 3) (``A^-1`` of the first half's ``q``) in place: on
    return ``r`` is the quasi-Newton step (the iterate moves by ``-r``)."""
    m = S.shape[0]
    for j in range(count - 1, -1, -1):
        k = (newest - j) % m
        bt = 0.0
        for i in range(r.shape[0]):
            bt += T[k, i, 0] * r[i, 0] + T[k, i, 1] * r[i, 1] + T[k, i, 2] * r[i, 2]
        c = alpha[k] - rho[k] * bt
        for i in range(r.shape[0]):
            r[i, 0] += c * S[k, i, 0]
            r[i, 1] += c * S[k, i, 1]
            r[i, 2] += c * S[k, i, 2]


@njit
def uzawa_energy(lam, nrm, x):
    """``-sum lam n . x``, J: the contact forces' energy at ``x`` (the line search's; the local step's energy,
    :func:`vfit_engine.kernels.pd.pd_rhs`, leaves them out, as they change between iterations)."""
    e = 0.0
    for i in range(x.shape[0]):
        if lam[i] > 0.0:
            e -= lam[i] * (nrm[i, 0] * x[i, 0] + nrm[i, 1] * x[i, 1] + nrm[i, 2] * x[i, 2])
    return e


@njit
def pair_energy(x, pi, pj, w):
    """``sum w |x_j - x_i|^2 / 2``, J: the stiffness damping's energy (its weights in the matrix; its pull towards
    the step's start is in the prediction, :func:`vfit_engine.kernels.pd_matrix.add_damping_target`)."""
    e = 0.0
    for q in range(pi.shape[0]):
        if w[q] != 0.0:
            i, j = pi[q], pj[q]
            dx, dy, dz = x[j, 0] - x[i, 0], x[j, 1] - x[i, 1], x[j, 2] - x[i, 2]
            e += 0.5 * w[q] * (dx * dx + dy * dy + dz * dz)
    return e


@njit
def max_move(r):
    """The largest vertex move ``|r_i|`` (m) of (n, 3) ``r``."""
    m = 0.0
    for i in range(r.shape[0]):
        q = r[i, 0] * r[i, 0] + r[i, 1] * r[i, 1] + r[i, 2] * r[i, 2]
        if q > m:
            m = q
    return m ** 0.5
