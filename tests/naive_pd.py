"""Slow, obvious NumPy/Python versions of the projective-dynamics kernels (:mod:`vfit_engine.kernels.pd`), for
tests only: each element's projection written out with rotation matrices and explicit loops, as the kernel's
docstring states it."""
import math

import numpy as np

from naive_sim import hinge_forces


def _band(d, lo, hi):
    length = np.linalg.norm(d)
    if length <= 0.0:
        return np.array([0.0, lo, 0.0])
    return d * (min(max(length, lo), hi) / length)


def _rotate(v, axis, angle):
    """``v`` turned by ``angle`` about unit ``axis`` (Rodrigues)."""
    return (v * math.cos(angle) + np.cross(axis, v) * math.sin(angle)
            + axis * np.dot(axis, v) * (1.0 - math.cos(angle)))


def corner_targets(u, v, t_lo, t_hi):
    """The arms ``u``, ``v`` of a corner with its angle brought into [t_lo, t_hi]: both turned in their plane by
    half the excess, towards each other when the angle is too wide (lengths kept)."""
    cosa = np.dot(u, v) / (np.linalg.norm(u) * np.linalg.norm(v))
    angle = math.acos(min(max(cosa, -1.0), 1.0))
    excess = angle - min(max(angle, t_lo), t_hi)
    if excess == 0.0:
        return u, v
    axis = np.cross(u, v)
    axis /= np.linalg.norm(axis)
    # turning u about u x v by a positive angle turns it towards v
    return _rotate(u, axis, 0.5 * excess), _rotate(v, -axis, 0.5 * excess)


def contact_push(x, inv_mass, pt_v, pt_b, planes):
    """(n, 3) m: each free vertex's mean push from the points below their planes (``planes``: a list of
    (point, normal (3,), offset) per listed half-space), the point's PBD move b_k g n / sum b^2."""
    push, count = np.zeros_like(x), np.zeros(len(x))
    for p, n, h in planes:
        pt = pt_b[p] @ x[pt_v[p]]
        g = h - n @ pt
        free = inv_mass[pt_v[p]] > 0
        den = np.sum(pt_b[p][free] ** 2)
        if g <= 0 or den <= 0:
            continue
        for k in range(3):
            v = pt_v[p, k]
            if free[k] and pt_b[p, k] != 0:
                push[v] += pt_b[p, k] * g / den * n
                count[v] += 1
    has = count > 0
    push[has] /= count[has, None]
    return push


def rhs(x, y, mh2, inv_mass, d_off, dist, corners, springs, hinges, pins, couplings, w_c, planes, pt_v, pt_b,
        lam, nrm):
    """``b`` of the global step at iterate ``x`` (:func:`vfit_engine.kernels.pd.pd_rhs`), from lists:
    dist/springs [(i, j, lo, hi, w)], corners [(i, j, k, t_lo, t_hi, w)], hinges (idx (H, 4), k, rest),
    pins [p], couplings [(i, p, w)], planes as :func:`contact_push`."""
    b = mh2[:, None] * y + d_off[:, None] * x
    for i, j, lo, hi, w in dist:
        p = _band(x[j] - x[i], lo, hi)
        b[j] += w * p
        b[i] -= w * p
    for i, j, k, t_lo, t_hi, w in corners:
        pu, pv = corner_targets(x[i] - x[k], x[j] - x[k], t_lo, t_hi)
        b[i] += w * pu
        b[k] -= w * pu
        b[j] += w * pv
        b[k] -= w * pv
    for i, j, lo, hi, w in springs:
        d = x[j] - x[i]
        f = w * (_band(d, lo, hi) - d)
        b[j] += f
        b[i] -= f
    idx, k, rest = hinges
    if len(idx):
        b += hinge_forces(x, x, 1.0, idx, k, np.zeros_like(k), rest)
    push = contact_push(x, inv_mass, pt_v, pt_b, planes)
    free = inv_mass > 0
    b[free] += w_c[free, None] * (x[free] + push[free])
    b += lam[:, None] * nrm
    for i, p, w in couplings:
        b[i] += w * x[p]
    for p in pins:
        b[p] = x[p]
    return b, push


def contact_forces(x, inv_mass, pt_v, pt_b, planes, rho, lam, nrm, plane, release=False):
    """``lam``, ``nrm``, ``plane`` after one Uzawa update (:func:`vfit_engine.kernels.pd.contact_forces`)."""
    lam, nrm, plane = lam.copy(), nrm.copy(), plane.copy()
    share = {}
    normal = {}
    for p, n, h in planes:
        pt = pt_b[p] @ x[pt_v[p]]
        g = h - n @ pt
        free = inv_mass[pt_v[p]] > 0
        den = np.sum(pt_b[p][free] ** 2)
        if den <= 0:
            continue
        for k in range(3):
            v = pt_v[p, k]
            if free[k] and pt_b[p, k] > 0:
                s = pt_b[p, k] * g / den
                share[v] = max(share.get(v, -np.inf), s)
                normal[v] = normal.get(v, 0.0) + pt_b[p, k] * n
    for i in range(len(x)):
        if i in share:
            nrm[i] = normal[i] / np.linalg.norm(normal[i])
            plane[i] = x[i] + share[i] * nrm[i]
            g = share[i]
        elif lam[i] > 0 and release:
            lam[i] = 0.0
            continue
        elif lam[i] > 0:
            g = nrm[i] @ (plane[i] - x[i])
        else:
            continue
        lam[i] = max(lam[i] + rho[i] * g, 0.0)
    return lam, nrm, plane


def energy(x, y, mh2, inv_mass, dist, corners, springs, hinges, w_c, planes, pt_v, pt_b, lam, nrm, x0, friction,
           damped):
    """The step's energy at ``x`` (:func:`vfit_engine.kernels.pd_energy.pd_energy`), from the lists of :func:`rhs`
    and ``damped`` [(i, j, dw)]: inertia, each element at its projection, the hinges' ``k (theta - theta0)^2 / 2``,
    the damping's ``dw |x_j - x_i|^2 / 2``, the contact weight on each push, Uzawa's ``-lam n . x`` and Coulomb's
    Huber function of the slip along the push's normal."""
    from vfit_engine.sim.bending import hinge_angles

    free = inv_mass > 0
    e = 0.5 * np.sum(mh2[free, None] * (x[free] - y[free]) ** 2)
    e -= np.sum((lam > 0) * np.einsum("ij,ij->i", nrm, x) * lam)
    for i, j, lo, hi, w in list(dist) + list(springs):
        d = x[j] - x[i]
        e += 0.5 * w * np.sum((d - _band(d, lo, hi)) ** 2)
    for i, j, k, t_lo, t_hi, w in corners:
        u, v = x[i] - x[k], x[j] - x[k]
        pu, pv = corner_targets(u, v, t_lo, t_hi)
        e += 0.5 * w * (np.sum((u - pu) ** 2) + np.sum((v - pv) ** 2))
    idx, k, rest = hinges
    if len(idx):
        d = (hinge_angles(idx, x) - rest + np.pi) % (2 * np.pi) - np.pi
        e += 0.5 * np.sum(k * d * d)
    for i, j, dw in damped:
        e += 0.5 * dw * np.sum((x[j] - x[i]) ** 2)
    push = contact_push(x, inv_mass, pt_v, pt_b, planes)
    for i in np.flatnonzero(free & (w_c > 0)):
        g = np.linalg.norm(push[i])
        e += 0.5 * w_c[i] * g * g
        force = w_c[i] * g + max(lam[i], 0.0)
        if friction <= 0 or force <= 0:
            continue
        n = nrm[i] if lam[i] > 0 else push[i] / g
        d = x[i] - x0[i]
        t = np.linalg.norm(d - (d @ n) * n)
        cone = friction * force / w_c[i]
        e += w_c[i] * (0.5 * t * t if t <= cone else cone * (t - 0.5 * cone))
    return e
