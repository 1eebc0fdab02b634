"""Baseline for the classic sphere drape: a plain Numba mass-spring cloth, independent of vfit's solver.

What a competent engineer writes without special tricks, as the issue that defined the benchmark measured
it ("a plain Numba mass-spring (Verlet, 40 substeps, 5 Provot iterations, two threads)"):

* an N x N quad grid of particles of equal mass (cotton, 0.15 kg/m^2 x 1 m^2 shared equally);
* structural (grid neighbours), shear (quad diagonals) and bend (second neighbours along rows and columns)
  springs with Hooke forces and damping along the spring,
  ``f_i = (k (l - l0) + kd (v_j - v_i) . u) u``, ``u = (x_j - x_i) / l``;
* position Verlet with air damping, ``x+ = x + e^(-a dt) (x - x-) + (f / m + g) dt^2``, 40 substeps a frame;
* Provot (1995) strain limiting: 5 Gauss-Seidel sweeps a substep over the structural springs, each spring
  longer than 1.10 l0 shortened back to it, both ends moving equally;
* the sphere: a particle inside radius x (1 + skin) is put on that surface radially and keeps
  ``1 - friction`` of its tangential velocity and none of its inward normal velocity;
* ``@numba.njit(parallel=True)``: forces gathered per particle (each spring seen from both ends, no
  races) and the integration in one ``prange`` over particles, the collision in another; the Provot
  sweep is serial (Gauss-Seidel on shared particles cannot be split naively); run on 2 threads.

Stiffness. The spring constants follow cotton's 2-D moduli on a regular grid (``k = K A / l0^2``:
structural K, shear K / 4, bend K / 2; damping likewise), but an explicit step cannot carry them
(at N = 100 and 40 substeps cotton's 2000 N/m is ~100x too stiff), so every constant is scaled by one
global factor that puts the stiffest particle at half the explicit stability bound
``w dt (2 sum k dt + 4 sum kd) < 4`` (Gershgorin); the cloth is then softer than cotton and Provot's
limiter supplies the inextensibility, as Provot proposed.

    python benchmarks/baseline_sphere_drape.py --n 100 [--threads 2] [--json]
"""
import argparse
import json
import math
import sys
import time

import numba
import numpy as np
from numba import prange

RADIUS = 0.3
HEIGHT = 0.5
FPS = 60
FRAMES = 120

AREAL_DENSITY = 0.15  # kg/m^2, cotton
STRETCH_K, SHEAR_K, BEND_K = 2000.0, 200.0, 20.0  # N/m, cotton's 2-D moduli
STRETCH_KD, SHEAR_KD, BEND_KD = 0.02, 0.01, 0.005  # N s/m
SUBSTEPS = 40
ITERATIONS = 5
STRAIN_LIMIT = 0.10
SKIN = 0.01
FRICTION = 0.5
AIR_DAMPING = 0.5  # 1/s
GRAVITY = -9.81  # m/s^2, along y
SAFETY = 0.5  # fraction of the explicit stability bound


def grid_springs(n, size=1.0):
    """Particles and springs of a horizontal n x n grid in the XZ plane, centred on the origin.

    Particle ``(i, j)`` (``i`` along x, ``j`` along z) has index ``j * n + i``.

    Returns
    -------
    pos : (n n, 3) float64, m
    springs : (s, 2) int64
        Structural, then shear, then bend.
    kind : (s,) int64
        0 structural, 1 shear, 2 bend.
    """
    xs = np.linspace(-0.5 * size, 0.5 * size, n)
    gx, gz = np.meshgrid(xs, xs)
    pos = np.stack([gx.ravel(), np.zeros(n * n), gz.ravel()], axis=1)
    idx = np.arange(n * n).reshape(n, n)  # [j, i]
    pairs = [
        (idx[:, :-1], idx[:, 1:], 0), (idx[:-1, :], idx[1:, :], 0),  # structural
        (idx[:-1, :-1], idx[1:, 1:], 1), (idx[:-1, 1:], idx[1:, :-1], 1),  # shear
        (idx[:, :-2], idx[:, 2:], 2), (idx[:-2, :], idx[2:, :], 2),  # bend
    ]
    springs = np.concatenate([np.stack([a.ravel(), b.ravel()], axis=1) for a, b, _ in pairs]).astype(np.int64)
    kind = np.concatenate([np.full(a.size, t) for a, _, t in pairs]).astype(np.int64)
    return pos, springs, kind


@numba.njit(parallel=True, cache=True)
def _drape_frame(x, xp, w, adj_off, adj_j, adj_rest, adj_k, adj_kd, lim_i, lim_j, lim_len,
                 centre, radius, friction, gravity_y, dt, keep, substeps, iterations, x_new):
    """``substeps`` steps of ``dt`` in place: x, xp (n, 3) m; w (n,) 1/kg; CSR springs per particle."""
    n = x.shape[0]
    inv_dt = 1.0 / dt
    dt2 = dt * dt
    for _ in range(substeps):
        # Hooke + damping forces gathered per particle, then Verlet
        for i in prange(n):
            vi0 = (x[i, 0] - xp[i, 0]) * inv_dt
            vi1 = (x[i, 1] - xp[i, 1]) * inv_dt
            vi2 = (x[i, 2] - xp[i, 2]) * inv_dt
            f0 = 0.0
            f1 = 0.0
            f2 = 0.0
            for e in range(adj_off[i], adj_off[i + 1]):
                j = adj_j[e]
                d0 = x[j, 0] - x[i, 0]
                d1 = x[j, 1] - x[i, 1]
                d2 = x[j, 2] - x[i, 2]
                length = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
                if length == 0.0:
                    continue
                u0 = d0 / length
                u1 = d1 / length
                u2 = d2 / length
                vrel = (((x[j, 0] - xp[j, 0]) * inv_dt - vi0) * u0 + ((x[j, 1] - xp[j, 1]) * inv_dt - vi1) * u1
                        + ((x[j, 2] - xp[j, 2]) * inv_dt - vi2) * u2)
                mag = adj_k[e] * (length - adj_rest[e]) + adj_kd[e] * vrel
                f0 += mag * u0
                f1 += mag * u1
                f2 += mag * u2
            x_new[i, 0] = x[i, 0] + keep * (x[i, 0] - xp[i, 0]) + w[i] * f0 * dt2
            x_new[i, 1] = x[i, 1] + keep * (x[i, 1] - xp[i, 1]) + (w[i] * f1 + gravity_y) * dt2
            x_new[i, 2] = x[i, 2] + keep * (x[i, 2] - xp[i, 2]) + w[i] * f2 * dt2
        for i in prange(n):
            for c in range(3):
                xp[i, c] = x[i, c]
                x[i, c] = x_new[i, c]
        # Provot strain limiting, Gauss-Seidel over the structural springs
        for _it in range(iterations):
            for s in range(lim_i.shape[0]):
                a = lim_i[s]
                b = lim_j[s]
                d0 = x[b, 0] - x[a, 0]
                d1 = x[b, 1] - x[a, 1]
                d2 = x[b, 2] - x[a, 2]
                length = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
                if length > lim_len[s]:
                    h = 0.5 * (length - lim_len[s]) / length
                    x[a, 0] += h * d0
                    x[a, 1] += h * d1
                    x[a, 2] += h * d2
                    x[b, 0] -= h * d0
                    x[b, 1] -= h * d1
                    x[b, 2] -= h * d2
        # sphere: radial push-out, friction on the tangential velocity, no bounce
        for i in prange(n):
            d0 = x[i, 0] - centre[0]
            d1 = x[i, 1] - centre[1]
            d2 = x[i, 2] - centre[2]
            r = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
            if r >= radius:
                continue
            if r > 0.0:
                n0 = d0 / r
                n1 = d1 / r
                n2 = d2 / r
            else:
                n0 = 0.0
                n1 = 1.0
                n2 = 0.0
            v0 = x[i, 0] - xp[i, 0]
            v1 = x[i, 1] - xp[i, 1]
            v2 = x[i, 2] - xp[i, 2]
            vn = v0 * n0 + v1 * n1 + v2 * n2
            t0 = (1.0 - friction) * (v0 - vn * n0)
            t1 = (1.0 - friction) * (v1 - vn * n1)
            t2 = (1.0 - friction) * (v2 - vn * n2)
            if vn < 0.0:
                vn = 0.0
            x[i, 0] = centre[0] + radius * n0
            x[i, 1] = centre[1] + radius * n1
            x[i, 2] = centre[2] + radius * n2
            xp[i, 0] = x[i, 0] - (t0 + vn * n0)
            xp[i, 1] = x[i, 1] - (t1 + vn * n1)
            xp[i, 2] = x[i, 2] - (t2 + vn * n2)


class BaselineDrape:
    """The drape scene for an n x n cloth (module docstring); ``step_frame()`` advances 1 / FPS s.

    Attributes
    ----------
    pos, pos_prev : (n n, 3) float64, m
    springs : (s, 2) int64;  kind : (s,) int64;  rest : (s,) float64, m
    stiffness_scale : float
        The global factor applied to cotton's spring constants for stability.
    """

    def __init__(self, n, substeps=SUBSTEPS, iterations=ITERATIONS, strain_limit=STRAIN_LIMIT):
        pos, springs, kind = grid_springs(int(n))
        pos[:, 1] = HEIGHT
        count = pos.shape[0]
        self.n, self.substeps, self.iterations = int(n), int(substeps), int(iterations)
        self.dt = 1.0 / FPS / self.substeps
        self.pos = np.ascontiguousarray(pos)
        self.pos_prev = self.pos.copy()  # at rest
        self.springs, self.kind = springs, kind
        self.rest = np.linalg.norm(pos[springs[:, 1]] - pos[springs[:, 0]], axis=1)
        mass = AREAL_DENSITY * 1.0 / count  # kg, equal shares of the 1 m^2 cloth
        self.inv_mass = np.full(count, 1.0 / mass)

        # k = K A / l0^2 on a regular grid: structural K, shear K / 4, bend K / 2
        k = np.array([STRETCH_K, SHEAR_K / 4, BEND_K / 2])[kind]
        kd = np.array([STRETCH_KD, SHEAR_KD / 4, BEND_KD / 2])[kind]
        ksum = np.bincount(springs.ravel(), np.repeat(k, 2), count)
        kdsum = np.bincount(springs.ravel(), np.repeat(kd, 2), count)
        demand = np.max(self.inv_mass * self.dt * (2.0 * ksum * self.dt + 4.0 * kdsum))
        self.stiffness_scale = min(1.0, 4.0 * SAFETY / demand)
        k, kd = k * self.stiffness_scale, kd * self.stiffness_scale

        # CSR: for each particle, its springs seen from its end
        owner = springs.T.ravel()
        other = springs[:, ::-1].T.ravel()
        spring = np.tile(np.arange(springs.shape[0]), 2)
        order = np.argsort(owner, kind="stable")
        self.adj_off = np.zeros(count + 1, np.int64)
        np.cumsum(np.bincount(owner, minlength=count), out=self.adj_off[1:])
        self.adj_j = np.ascontiguousarray(other[order])
        self.adj_rest = np.ascontiguousarray(self.rest[spring[order]])
        self.adj_k = np.ascontiguousarray(k[spring[order]])
        self.adj_kd = np.ascontiguousarray(kd[spring[order]])

        limited = kind == 0
        self.lim_i = np.ascontiguousarray(springs[limited, 0])
        self.lim_j = np.ascontiguousarray(springs[limited, 1])
        self.lim_len = np.ascontiguousarray(self.rest[limited] * (1.0 + strain_limit))
        self.centre = np.zeros(3)
        self.keep = math.exp(-AIR_DAMPING * self.dt)
        self._x_new = np.zeros_like(self.pos)

    def step_frame(self):
        """Advance one frame (``substeps`` steps of ``dt``), in place."""
        _drape_frame(self.pos, self.pos_prev, self.inv_mass, self.adj_off, self.adj_j, self.adj_rest, self.adj_k,
                   self.adj_kd, self.lim_i, self.lim_j, self.lim_len, self.centre, RADIUS * (1.0 + SKIN), FRICTION,
                   GRAVITY, self.dt, self.keep, self.substeps, self.iterations, self._x_new)

    def max_stretch(self):
        """Largest strain ``l / l0 - 1`` of a structural spring."""
        s = self.springs[self.kind == 0]
        length = np.linalg.norm(self.pos[s[:, 1]] - self.pos[s[:, 0]], axis=1)
        return float(np.max(length / self.rest[self.kind == 0] - 1.0))

    def max_pen_mm(self):
        """Deepest particle inside the true sphere (radius 0.3 m), mm; 0 when none is inside."""
        r = np.linalg.norm(self.pos - self.centre, axis=1)
        return float(max(RADIUS - r.min(), 0.0) * 1000.0)


def run(n, frames=FRAMES, threads=2):
    """Drape an n x n cloth for ``frames`` frames on ``threads`` numba threads.

    Returns
    -------
    wall : float, s
    cpu : float, s
        Process CPU time (all threads; numba's OpenMP workers also count while they spin).
    drape : BaselineDrape
    """
    before = numba.get_num_threads()
    numba.set_num_threads(min(int(threads), numba.config.NUMBA_NUM_THREADS))
    try:
        drape = BaselineDrape(n)
        t0, c0 = time.perf_counter(), time.process_time()
        for _ in range(frames):
            drape.step_frame()
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    finally:
        numba.set_num_threads(before)
    return wall, cpu, drape


def summary(wall, cpu, drape, frames=FRAMES):
    """The figures of one run, as a dict."""
    return dict(
        n=drape.n, substeps=drape.substeps, iterations=drape.iterations, wall_s=round(wall, 4), cpu_s=round(cpu, 4),
        ms_per_frame=round(1000 * wall / frames, 3),
        particle_substeps_per_s=float(f"{drape.n ** 2 * drape.substeps * frames / wall:.4g}"),
        max_stretch=round(drape.max_stretch(), 5), max_pen_mm=round(drape.max_pen_mm(), 4),
        finite=bool(np.all(np.isfinite(drape.pos))), min_y=round(float(drape.pos[:, 1].min()), 4),
        stiffness_scale=float(f"{drape.stiffness_scale:.4g}"),
    )


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=100, help="particles per side")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    run(4, frames=1, threads=args.threads)  # compiles (or loads from cache)
    compile_s = time.perf_counter() - t0
    result = summary(*run(args.n, threads=args.threads))
    result.update(threads=args.threads, compile_s=round(compile_s, 3))
    if args.json:
        print(json.dumps(result))
    else:
        for k, v in result.items():
            print(f"{k:>24}: {v}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
