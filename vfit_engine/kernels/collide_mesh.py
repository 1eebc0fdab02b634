"""Numba kernels for the exact body-mesh collider (signed distance to a triangle mesh).

Acceleration structure (:data:`BodyGrid`, built by :class:`vfit_engine.collide.body_mesh.MeshCollider`
with :mod:`.collide_mesh_build` and :mod:`.collide_mesh_empty`): a dense uniform grid of cubic
cells of edge ``h`` in CSR layout (``cell_start``, ``cell_tris``). A triangle is listed in
every cell whose centre lies within ``reach = margin + h*sqrt(3)/2`` of the triangle, so a
cell lists every triangle that comes within ``margin`` of any point of the cell. Hence a
point's own cell already holds its exact closest triangle whenever the distance is <= margin,
and a search over the Chebyshev shells k = 0, 1, 2 ... around the point's cell is exact once
``best <= k*h + b + margin`` (b: distance from the point to its own cell's faces), because a
triangle at distance t has a point of its margin-neighbourhood at distance max(0, t - margin)
from the query point; or once ``best <= reach - |p - c|`` (c the own cell's centre: an unlisted
triangle is farther than reach from c), which is never later and often a shell earlier.

``cell_sd`` holds the signed distance of every cell centre (exact for cells with
triangles, a lower bound on the magnitude with the right sign for empty cells), so
``cell_sd -/+ h*sqrt(3)/2`` bounds the signed distance of any point in the cell:
points certainly farther than the requested band are answered without touching a
triangle, which is what keeps ``project`` cheap for cloth hanging off the body.

Sign: the closest feature's angle-weighted pseudo-normal (Baerentzen & Aanaes 2005,
"Signed distance computation using the angle weighted pseudonormal", IEEE TVCG 11(3)):
face normal for a face, the sum of the two face normals for an edge, the
angle-weighted sum of the incident face normals for a vertex; ``sign((p - q) . n)``.

Closest point on a triangle: Ericson, Real-Time Collision Detection (2005), 5.1.5,
with its Voronoi-region tests reused as the feature code.

The kernels are serial: on the 2-core benchmark machine ``parallel=True`` made
``project_points`` slower (7.6 ms vs 5.5 ms for 8,000 points; the queries are bound by
memory latency), and the cloth solver around it has its own threads.
"""
import math
from collections import namedtuple

import numpy as np

from vfit_engine._jit import njit

#: The body grid as every kernel takes it (:attr:`vfit_engine.collide.body_mesh.MeshCollider.grid`).
#: Triangles are in the grid's own (Z-curve) order, ``t`` below:
#:
#: * tri_data (t, 16) float64, m: per triangle bounding box min xyz, max xyz, corners a, b, c and one
#:   pad: one 128-byte record, so a triangle costs two cache lines;
#: * tris (t, 3) int64: vertex indices (for the vertex pseudo-normals);
#: * tri_normals (t, 3) float64: unit face normals (zero for a zero-area triangle);
#: * tri_edges (t, 3) int64: edge index of (v0 v1), (v1 v2), (v2 v0);
#: * edge_normals (e, 3), vert_normals (v, 3) float64: angle-weighted pseudo-normals (Baerentzen &
#:   Aanaes 2005);
#: * origin (3,) float64, m; dims (3,) int64; h, margin float, m: grid corner, cell counts, cell edge
#:   and the exact band of one cell (cell ``(i, j, k)`` is ``(i * ny + j) * nz + k``);
#: * cell_start (nx*ny*nz + 1,) int64; cell_tris (m,) int64; cell_tdist (m,) float64, m: CSR
#:   triangle lists; ``cell_tdist`` is a lower bound on the triangle's distance to the cell centre
#:   (the floor of its distance level, reach / 64 wide: :mod:`.collide_mesh_build`), never decreasing along a list;
#: * cell_sd (nx*ny*nz,) float64, m: signed distance of each cell centre (exact where the cell
#:   lists triangles, else a lower bound on the magnitude with the right sign);
#: * cell_sd_hi (nx*ny*nz,) float64, m: for a body that moves while one grid serves it
#:   (:class:`vfit_engine.collide.moving_body.MovingBodyCollider`), ``cell_sd`` is a lower bound
#:   and ``cell_sd_hi`` an upper bound of each centre's signed distance at any time the grid serves;
#:   a still body passes ``cell_sd`` itself (the default: a one-cell placeholder for an empty grid).
BodyGrid = namedtuple("BodyGrid", ["tri_data", "tris", "tri_normals", "tri_edges", "edge_normals", "vert_normals",
                                   "origin", "dims", "h", "margin", "cell_start", "cell_tris", "cell_tdist",
                                   "cell_sd", "cell_sd_hi"], defaults=(np.zeros(1),))

# feature codes returned by closest_on_triangle
_FACE = 0  # 1, 2, 3: vertex 0, 1, 2; 4, 5, 6: edge 0 (v0 v1), 1 (v1 v2), 2 (v2 v0)

#: Below this distance (m) the direction p - q is rounding noise: use the pseudo-normal.
DIRECTION_EPS = 1e-9


@njit
def _closest_on_segment(px, py, pz, ax, ay, az, bx, by, bz):
    """Closest point on segment ab and its parameter in [0, 1]."""
    ex, ey, ez = bx - ax, by - ay, bz - az
    ee = ex * ex + ey * ey + ez * ez
    t = 0.0
    if ee > 0.0:
        t = ((px - ax) * ex + (py - ay) * ey + (pz - az) * ez) / ee
        t = min(max(t, 0.0), 1.0)
    return ax + t * ex, ay + t * ey, az + t * ez, t


@njit
def closest_on_triangle(px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz):
    """Closest point q on triangle abc to p and the feature it lies on (Ericson 5.1.5).

    Returns ``(qx, qy, qz, feature)`` with feature 0 face, 1..3 vertex a, b, c,
    4..6 edge ab, bc, ca. A zero-area triangle falls back to its three edges.
    """
    abx, aby, abz = bx - ax, by - ay, bz - az
    acx, acy, acz = cx - ax, cy - ay, cz - az
    apx, apy, apz = px - ax, py - ay, pz - az
    d1 = abx * apx + aby * apy + abz * apz
    d2 = acx * apx + acy * apy + acz * apz
    if d1 <= 0.0 and d2 <= 0.0:
        return ax, ay, az, 1
    bpx, bpy, bpz = px - bx, py - by, pz - bz
    d3 = abx * bpx + aby * bpy + abz * bpz
    d4 = acx * bpx + acy * bpy + acz * bpz
    if d3 >= 0.0 and d4 <= d3:
        return bx, by, bz, 2
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0 and d1 - d3 > 0.0:
        v = d1 / (d1 - d3)
        return ax + v * abx, ay + v * aby, az + v * abz, 4
    cpx, cpy, cpz = px - cx, py - cy, pz - cz
    d5 = abx * cpx + aby * cpy + abz * cpz
    d6 = acx * cpx + acy * cpy + acz * cpz
    if d6 >= 0.0 and d5 <= d6:
        return cx, cy, cz, 3
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0 and d2 - d6 > 0.0:
        w = d2 / (d2 - d6)
        return ax + w * acx, ay + w * acy, az + w * acz, 6
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0 and (d4 - d3) + (d5 - d6) > 0.0:
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        return bx + w * (cx - bx), by + w * (cy - by), bz + w * (cz - bz), 5
    den = va + vb + vc
    if den > 0.0:
        v = vb / den
        w = vc / den
        return ax + abx * v + acx * w, ay + aby * v + acy * w, az + abz * v + acz * w, 0
    # degenerate (zero-area) triangle: best of its edges
    best = np.inf
    qx, qy, qz, f = ax, ay, az, 1
    for e in range(3):
        if e == 0:
            sx, sy, sz, t = _closest_on_segment(px, py, pz, ax, ay, az, bx, by, bz)
        elif e == 1:
            sx, sy, sz, t = _closest_on_segment(px, py, pz, bx, by, bz, cx, cy, cz)
        else:
            sx, sy, sz, t = _closest_on_segment(px, py, pz, cx, cy, cz, ax, ay, az)
        dd = (px - sx) ** 2 + (py - sy) ** 2 + (pz - sz) ** 2
        if dd < best:
            best = dd
            qx, qy, qz = sx, sy, sz
            f = 4 + e if 0.0 < t < 1.0 else (1 + e if t <= 0.0 else 1 + (e + 1) % 3)
    return qx, qy, qz, f


@njit(inline="always")
def _scan_cell(px, py, pz, c, gap, tri_data, cell_start, cell_tris, cell_tdist, best2, best_t, best_f, bqx, bqy, bqz):
    """Test the triangles of cell ``c`` against the current best (squared distance).

    ``cell_tdist`` bounds the distance to the cell centre from below and never decreases
    along the list, and ``gap`` >= |p - centre|, so ``dist(p, T) >= cell_tdist - gap`` ends the
    scan at the first triangle from which on none can win.
    """
    best = math.sqrt(best2)
    for s in range(cell_start[c], cell_start[c + 1]):
        if cell_tdist[s] - gap >= best:
            break
        t = cell_tris[s]
        # the triangle's bounding box is a cheap lower bound on its distance
        ex = max(tri_data[t, 0] - px, 0.0, px - tri_data[t, 3])
        ey = max(tri_data[t, 1] - py, 0.0, py - tri_data[t, 4])
        ez = max(tri_data[t, 2] - pz, 0.0, pz - tri_data[t, 5])
        if ex * ex + ey * ey + ez * ez >= best2:
            continue
        qx, qy, qz, f = closest_on_triangle(px, py, pz, tri_data[t, 6], tri_data[t, 7], tri_data[t, 8],
                                            tri_data[t, 9], tri_data[t, 10], tri_data[t, 11],
                                            tri_data[t, 12], tri_data[t, 13], tri_data[t, 14])
        dd = (px - qx) ** 2 + (py - qy) ** 2 + (pz - qz) ** 2
        if dd < best2:
            best2, best_t, best_f, bqx, bqy, bqz = dd, t, f, qx, qy, qz
            best = math.sqrt(dd)
    return best2, best_t, best_f, bqx, bqy, bqz


@njit(inline="always")
def signed_result(px, py, pz, qx, qy, qz, best2, t, f, tris, tri_normals, tri_edges, edge_normals, vert_normals):
    """``(d, qx, qy, qz, nx, ny, nz, t)`` of point p whose closest point q lies on feature f of triangle t.

    The sign is that of ``(p - q) . n`` with n the feature's pseudo-normal (module docstring).
    """
    if f == _FACE:
        fnx, fny, fnz = tri_normals[t, 0], tri_normals[t, 1], tri_normals[t, 2]
    elif f <= 3:
        v = tris[t, f - 1]
        fnx, fny, fnz = vert_normals[v, 0], vert_normals[v, 1], vert_normals[v, 2]
    else:
        e = tri_edges[t, f - 4]
        fnx, fny, fnz = edge_normals[e, 0], edge_normals[e, 1], edge_normals[e, 2]
    wx, wy, wz = px - qx, py - qy, pz - qz
    dist = math.sqrt(best2)
    sgn = -1.0 if wx * fnx + wy * fny + wz * fnz < 0.0 else 1.0
    if dist > DIRECTION_EPS:
        inv = sgn / dist
        nx, ny, nz = wx * inv, wy * inv, wz * inv
    else:
        nx, ny, nz = fnx, fny, fnz
    return sgn * dist, qx, qy, qz, nx, ny, nz, t


@njit
def query_point(px, py, pz, grid, trust_sd, max_out, max_in, floored=False):
    """Signed distance of one point by the shell search described in the module docstring.

    Parameters
    ----------
    px, py, pz : float, m
    grid : BodyGrid
    trust_sd : bool
        Use the cell centre's exact distance as a first bound (True for every caller but
        tests of the search itself).
    max_out, max_in : float, m
        Exact when ``-max_in < d < max_out``; a point proven outside that band returns
        ``d = +inf`` (outside) or ``-inf`` (inside) with ``tri = -1``.
    floored : bool
        The caller knows the point is no deeper than ``max_in`` inside the body (an earlier query and how far
        point and body moved since): the search then ends at the wider of the two bands even where the cell does
        not tell the point's side, and a point found farther is outside (``+inf``; ``-inf`` if its cell lies
        wholly inside the body, which the caller's knowledge rules out). Without it such a point is
        searched until its closest triangle is found, however far: on a moving body's grid, whose cells near
        a fast limb do not know their side, a point hovering 5 cm off took ~70 us.

    Returns
    -------
    tuple
        ``(d, qx, qy, qz, nx, ny, nz, tri)``: signed distance (m, negative inside), closest
        point, unit outward normal (direction from q to p times the sign, the pseudo-normal
        when |d| < DIRECTION_EPS) and triangle index (grid order).
    """
    # the helpers below are inlined (inline="always"): a call taking arrays costs reference
    # counting, which made every query ~40 % slower when the grid was passed on to them
    tri_data, tris, tri_normals, tri_edges = grid.tri_data, grid.tris, grid.tri_normals, grid.tri_edges
    edge_normals, vert_normals = grid.edge_normals, grid.vert_normals
    origin, dims, h, margin = grid.origin, grid.dims, grid.h, grid.margin
    cell_start, cell_tris, cell_tdist, cell_sd = grid.cell_start, grid.cell_tris, grid.cell_tdist, grid.cell_sd
    cell_sd_hi = grid.cell_sd_hi
    nx_, ny_, nz_ = dims[0], dims[1], dims[2]
    half = 0.5 * math.sqrt(3.0) * h
    # clamp into the grid box; outside it |p - y|^2 >= |p - p'|^2 + |p' - y|^2 for every y in the box
    cx_ = min(max(px, origin[0]), origin[0] + nx_ * h)
    cy_ = min(max(py, origin[1]), origin[1] + ny_ * h)
    cz_ = min(max(pz, origin[2]), origin[2] + nz_ * h)
    g2 = (px - cx_) ** 2 + (py - cy_) ** 2 + (pz - cz_) ** 2
    far_out = (np.inf, np.nan, np.nan, np.nan, 0.0, 0.0, 0.0, -1)
    far_in = (-np.inf, np.nan, np.nan, np.nan, 0.0, 0.0, 0.0, -1)
    if g2 > 0.0 and g2 >= max_out * max_out:
        return far_out
    fx = (cx_ - origin[0]) / h
    fy = (cy_ - origin[1]) / h
    fz = (cz_ - origin[2]) / h
    i = min(max(int(fx), 0), nx_ - 1)
    j = min(max(int(fy), 0), ny_ - 1)
    k = min(max(int(fz), 0), nz_ - 1)
    c0 = (i * ny_ + j) * nz_ + k
    s = cell_sd[c0]  # s <= the centre's signed distance <= s_hi (equal for a still body)
    s_hi = cell_sd_hi[c0]
    if s - half >= max_out:
        return far_out
    if s_hi + half <= -max_in:
        return far_in
    # |s| > half: the whole cell is on the side of its centre (the signed distance is 1-Lipschitz),
    # so only triangles nearer than that side's bound matter; otherwise the point is within
    # 2 half <= margin of the surface and its own cell answers it exactly
    if g2 > 0.0 or s > half:
        cap = max_out
    elif s_hi < -half:
        cap = max_in
    else:
        cap = np.inf
    if floored:
        cap = min(cap, max(max_out, max_in))
    if trust_sd and g2 == 0.0 and cell_start[c0] < cell_start[c0 + 1]:
        # exact centre distance (cells with triangles): |d(p)| <= |s| + half, a tight first bound
        cap = min(cap, max(abs(s), abs(s_hi)) + half * (1.0 + 1e-9))
    b = min(fx - i, i + 1 - fx, fy - j, j + 1 - fy, fz - k, k + 1 - fz) * h
    b = max(b, 0.0)
    # the own cell lists every triangle within margin + half of its centre, so an unlisted one is
    # farther than margin + half - |p - centre| from p: at least as good a stop as the shells' b + margin
    ox = origin[0] + (i + 0.5) * h - px
    oy = origin[1] + (j + 0.5) * h - py
    oz = origin[2] + (k + 0.5) * h - pz
    own = margin + half - math.sqrt(ox * ox + oy * oy + oz * oz)
    best2, best_t, best_f = cap * cap, -1, -1
    qx, qy, qz = np.nan, np.nan, np.nan
    kmax = max(nx_, ny_, nz_)
    ring = 0
    while True:
        for di in range(-ring, ring + 1):
            ii = i + di
            if ii < 0 or ii >= nx_:
                continue
            for dj in range(-ring, ring + 1):
                jj = j + dj
                if jj < 0 or jj >= ny_:
                    continue
                step = 1 if (di == -ring or di == ring or dj == -ring or dj == ring) else 2 * ring
                for dk in range(-ring, ring + 1, step):
                    kk = k + dk
                    if kk < 0 or kk >= nz_:
                        continue
                    cc = (ii * ny_ + jj) * nz_ + kk
                    if cell_start[cc] == cell_start[cc + 1]:
                        continue
                    ox = origin[0] + (ii + 0.5) * h - px
                    oy = origin[1] + (jj + 0.5) * h - py
                    oz = origin[2] + (kk + 0.5) * h - pz
                    gap = math.sqrt(ox * ox + oy * oy + oz * oz)
                    best2, best_t, best_f, qx, qy, qz = _scan_cell(
                        px, py, pz, cc, gap, tri_data, cell_start, cell_tris, cell_tdist,
                        best2, best_t, best_f, qx, qy, qz)
        reach_k = ring * h + b
        bound = max(math.sqrt(g2 + reach_k * reach_k) + margin, own)  # no unvisited triangle is closer
        if best2 <= bound * bound or ring > kmax:
            break
        ring += 1
    if best_t < 0:
        return far_in if s_hi < 0.0 and g2 == 0.0 else far_out
    return signed_result(px, py, pz, qx, qy, qz, best2, best_t, best_f, tris, tri_normals, tri_edges,
                         edge_normals, vert_normals)


@njit
def closest_points(points, grid, max_out, max_in, d_out, closest_out, normal_out, tri_out):
    """Signed distance, closest point, outward normal and triangle of every point.

    Parameters
    ----------
    points : (n, 3) float64, m
    grid : BodyGrid
        The body (module docstring and :data:`BodyGrid`).
    max_out, max_in : float, m
        Band of interest: exact for ``-max_in < d < max_out``; beyond it a point may be
        reported as ``+inf`` / ``-inf`` (closest NaN, normal 0, tri -1).
    d_out : (n,), closest_out : (n, 3), normal_out : (n, 3) float64;  tri_out : (n,) int64
        Outputs; d (m) is negative inside; tri in the grid's triangle order.
    """
    for p in range(points.shape[0]):
        d, qx, qy, qz, nx, ny, nz, t = query_point(points[p, 0], points[p, 1], points[p, 2], grid, True,
                                                   max_out, max_in)
        d_out[p] = d
        closest_out[p, 0], closest_out[p, 1], closest_out[p, 2] = qx, qy, qz
        normal_out[p, 0], normal_out[p, 1], normal_out[p, 2] = nx, ny, nz
        tri_out[p] = t


@njit
def project_points(x, x_prev, inv_mass, grid, skin, friction, restitution, max_push, max_in):
    """Push particles out of the body to ``skin`` and apply restitution and friction (in place).

    For each particle with ``inv_mass > 0`` and signed distance ``d < skin``:
    ``x' = x + dx`` with ``dx = q + skin*n - x`` (n the outward normal at the closest
    point q), shortened to ``max_push`` (m) if longer. The displacement of the step,
    ``v = x - x_prev``, is split into ``vn = v.n`` and ``vt = v - vn*n``; an approaching
    ``vn < 0`` becomes ``-restitution*vn`` (Newton's law), and the tangential part is
    reduced Coulomb-like by the normal change: ``|vt'| = max(0, |vt| - friction*(vn' - vn))``.
    Then ``x_prev = x' - (vn'*n + vt')``, so the positional correction itself adds no
    velocity (a particle that starts inside comes out without being launched).

    Parameters
    ----------
    x, x_prev : (n, 3) float64, m
        Positions and previous positions, modified in place.
    inv_mass : (n,) float64, 1/kg
        Particles with ``inv_mass <= 0`` are pinned and never touched.
    grid : BodyGrid
    skin, friction, restitution, max_push, max_in : float
        Offset (m), Coulomb coefficient, coefficient of restitution, the longest
        correction per call (m, inf for none) and the depth (m) beyond which an inside
        particle is left alone (inf: always searched).

    Returns
    -------
    int
        Number of particles corrected.
    """
    count = 0
    for p in range(x.shape[0]):
        if inv_mass[p] <= 0.0:
            continue
        px, py, pz = x[p, 0], x[p, 1], x[p, 2]
        d, qx, qy, qz, nx, ny, nz, t = query_point(px, py, pz, grid, True, skin, max_in)
        # the relative tolerance keeps particles already at the skin (to rounding) from re-counting
        if t < 0 or not d < skin * (1.0 - 1e-9):
            continue
        dx = qx + skin * nx - px
        dy = qy + skin * ny - py
        dz = qz + skin * nz - pz
        dl = math.sqrt(dx * dx + dy * dy + dz * dz)
        if dl > max_push:
            sc = max_push / dl
            dx, dy, dz = dx * sc, dy * sc, dz * sc
        vx, vy, vz = px - x_prev[p, 0], py - x_prev[p, 1], pz - x_prev[p, 2]
        vn = vx * nx + vy * ny + vz * nz
        tx, ty, tz = vx - vn * nx, vy - vn * ny, vz - vn * nz
        vn_new = -restitution * vn if vn < 0.0 else vn
        vt = math.sqrt(tx * tx + ty * ty + tz * tz)
        scale = 0.0
        if vt > 0.0:
            scale = max(0.0, vt - friction * (vn_new - vn)) / vt
        x[p, 0], x[p, 1], x[p, 2] = px + dx, py + dy, pz + dz
        x_prev[p, 0] = x[p, 0] - (vn_new * nx + scale * tx)
        x_prev[p, 1] = x[p, 1] - (vn_new * ny + scale * ty)
        x_prev[p, 2] = x[p, 2] - (vn_new * nz + scale * tz)
        count += 1
    return count


@njit
def cell_centre_sd(cells, grid, cell_sd_out):
    """Exact signed distance of the centres of ``cells`` (k,) int64, written to ``cell_sd_out`` (ncells,) m.

    Every cell of ``cells`` must list triangles. Its list holds every triangle within
    ``margin + h*sqrt(3)/2`` of the centre, ordered by distance level, so the centre's closest
    triangle is among those of the first level (``grid.cell_sd`` is not read).
    """
    origin, h = grid.origin, grid.h
    ny_, nz_ = grid.dims[1], grid.dims[2]
    tri_data, cell_start, cell_tris, cell_tdist = grid.tri_data, grid.cell_start, grid.cell_tris, grid.cell_tdist
    for m in range(cells.shape[0]):
        cc = cells[m]
        i = cc // (ny_ * nz_)
        j = (cc // nz_) % ny_
        k = cc % nz_
        px, py, pz = origin[0] + (i + 0.5) * h, origin[1] + (j + 0.5) * h, origin[2] + (k + 0.5) * h
        a = cell_start[cc]
        best2, best_t, best_f, bqx, bqy, bqz = np.inf, -1, -1, np.nan, np.nan, np.nan
        for s in range(a, cell_start[cc + 1]):
            if cell_tdist[s] > cell_tdist[a]:
                break
            t = cell_tris[s]
            qx, qy, qz, f = closest_on_triangle(px, py, pz, tri_data[t, 6], tri_data[t, 7], tri_data[t, 8],
                                                tri_data[t, 9], tri_data[t, 10], tri_data[t, 11],
                                                tri_data[t, 12], tri_data[t, 13], tri_data[t, 14])
            dd = (px - qx) ** 2 + (py - qy) ** 2 + (pz - qz) ** 2
            if dd < best2:
                best2, best_t, best_f, bqx, bqy, bqz = dd, t, f, qx, qy, qz
        cell_sd_out[cc] = signed_result(px, py, pz, bqx, bqy, bqz, best2, best_t, best_f, grid.tris,
                                        grid.tri_normals, grid.tri_edges, grid.edge_normals, grid.vert_normals)[0]
