"""Slow, obvious NumPy/Python versions of the cloth kernels, for tests only."""
import numpy as np


def spring_forces(x, xp, dt, idx, rest, k, kd):
    """Damped Hooke forces, N: f_i = [k (l - l0) + kd (v_j - v_i).u] u, f_j = -f_i."""
    v = (x - xp) / dt
    d = x[idx[:, 1]] - x[idx[:, 0]]
    length = np.linalg.norm(d, axis=1)
    u = d / length[:, None]
    vr = np.sum((v[idx[:, 1]] - v[idx[:, 0]]) * u, axis=1)
    fs = (k * (length - rest) + kd * vr)[:, None] * u
    f = np.zeros_like(x)
    np.add.at(f, idx[:, 0], fs)
    np.add.at(f, idx[:, 1], -fs)
    return f


def integrate(x, xp, inv_mass, f, gravity, dt, c):
    """x+ = x + (1 - c)(x - x-) + (w f + g) dt^2 for free particles; pinned keep x."""
    a = inv_mass[:, None] * f + np.asarray(gravity)[None, :]
    out = x + (1.0 - c) * (x - xp) + a * dt * dt
    pinned = inv_mass == 0
    out[pinned] = x[pinned]
    return out


def strain_limit_sweep(x, inv_mass, idx, max_len, omega=1.0):
    """One Gauss-Seidel sweep of Provot strain limiting, springs in the given order (copy)."""
    x = x.copy()
    for (i, j), lmax in zip(idx, max_len):
        wi, wj = inv_mass[i], inv_mass[j]
        if wi + wj == 0:
            continue
        d = x[j] - x[i]
        length = np.sqrt(d @ d)
        if length > lmax:
            corr = omega * (length - lmax) / length * d / (wi + wj)
            x[i] = x[i] + wi * corr
            x[j] = x[j] - wj * corr
    return x


def collide_spheres(x, xp, inv_mass, centres, radii, friction, restitution):
    """Project free particles out of spheres, friction/restitution on x - x_prev (copies)."""
    x = x.copy()
    xp = xp.copy()
    for i in range(x.shape[0]):
        if inv_mass[i] == 0:
            continue
        for c, r, cf, cr in zip(centres, radii, friction, restitution):
            d = x[i] - c
            dist = np.linalg.norm(d)
            if dist >= r:
                continue
            n = d / dist if dist > 0 else np.array([0.0, 1.0, 0.0])
            v = x[i] - xp[i]
            vn = v @ n
            vt = v - vn * n
            vn_new = -cr * vn if vn < 0 else vn
            x[i] = c + r * n
            xp[i] = x[i] - ((1 - cf) * vt + vn_new * n)
    return x, xp


def substep(x, xp, inv_mass, gravity, idx, rest, k, kd, lim_idx, lim_len, iterations, omega,
            centres, radii, friction, restitution, dt, c_air):
    """One whole solver substep: forces, Verlet, strain limiting, spheres (copies)."""
    f = spring_forces(x, xp, dt, idx, rest, k, kd)
    x_new = integrate(x, xp, inv_mass, f, gravity, dt, c_air)
    xp_new = x.copy()
    for _ in range(iterations):
        x_new = strain_limit_sweep(x_new, inv_mass, lim_idx, lim_len, omega)
    return collide_spheres(x_new, xp_new, inv_mass, centres, radii, friction, restitution)
