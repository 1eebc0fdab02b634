"""Numba kernels that build the body-mesh collider's grid (:data:`.collide_mesh.BodyGrid`).

:class:`vfit_engine.collide.body_mesh.MeshCollider` runs them in this order:

1. :func:`mesh_edges` (once per triangle list) and :func:`mesh_normals` (per pose): edge
   numbering and the angle-weighted pseudo-normals (Baerentzen & Aanaes 2005).
2. :func:`bin_triangles`: every (cell, triangle) pair whose cell centre lies within ``reach`` of
   the triangle, with its distance level; triangle-major, so each triangle's precomputed edge
   data serves its ~140 cells.
3. :func:`cell_lists`: the pairs grouped by cell (CSR), each list ordered by distance level.
4. :func:`.collide_mesh.cell_centre_sd`: the exact signed distance of every listed cell's centre
   (its closest triangle is on the list's first level).
5. :func:`.collide_mesh_empty.empty_cell_sd`: the cells without triangles.

What the build is bound by (hm08: 26,756 triangles, 0.89 M cells, 3.8 M pairs; the 2-core
benchmark machine streams ~6 GB/s per core): passes over the pairs. So the pairs are binned
once (the former count-then-fill ran the closest-point test twice), kept compact (int32, a
one-byte distance level), and each list is ordered by one of ``LEVELS`` distance levels with
a counting sort instead of a full sort by distance (an allocating ``argsort`` per cell took
0.2 s). ``cell_tdist`` then holds level floors: the search's early exit only needs a lower
bound that does not decrease along the list, and 0.45 mm levels (hm08) cost it nothing measurable.

Numba's cache watches only this file (nothing here inlines helpers from elsewhere).
"""
import math

import numpy as np

from vfit_engine._jit import njit


@njit
def mesh_edges(tris, vert_count, tri_edges_out):
    """Number the undirected edges of ``tris`` (t, 3) int64 in order of (lower, higher) vertex.

    ``tri_edges_out`` (t, 3) int64 receives the edge of (v0 v1), (v1 v2), (v2 v0); returns the
    edge count. Same numbering as ``np.unique`` of the sorted vertex pairs.
    """
    nt = tris.shape[0]
    keys = np.empty(3 * nt, dtype=np.int64)
    for t in range(nt):
        for k in range(3):
            u, w = tris[t, k], tris[t, (k + 1) % 3]
            keys[3 * t + k] = min(u, w) * vert_count + max(u, w)
    order = np.argsort(keys)
    e = -1
    prev = -1
    for s in order:
        if keys[s] != prev:
            e += 1
            prev = keys[s]
        tri_edges_out[s // 3, s % 3] = e
    return e + 1


@njit
def mesh_normals(verts, tris, tri_edges, tri_normals_out, edge_normals_out, vert_normals_out):
    """Unit face normals and the pseudo-normals of edges and vertices (Baerentzen & Aanaes 2005).

    Parameters
    ----------
    verts : (v, 3) float64, m
    tris, tri_edges : (t, 3) int64
        Triangles and their edges (:func:`mesh_edges`).
    tri_normals_out : (t, 3) float64
        ``(b - a) x (c - a) / |...|``, zero for a zero-area triangle.
    edge_normals_out : (e, 3) float64
        Normalised sum of the normals of the triangles on the edge.
    vert_normals_out : (v, 3) float64
        Normalised sum of the incident face normals, each weighted by the triangle's angle at
        the vertex (``atan2(|u x w|, u . w)``).
    """
    edge_normals_out[:] = 0.0
    vert_normals_out[:] = 0.0
    for t in range(tris.shape[0]):
        a, b, c = tris[t, 0], tris[t, 1], tris[t, 2]
        abx, aby, abz = verts[b, 0] - verts[a, 0], verts[b, 1] - verts[a, 1], verts[b, 2] - verts[a, 2]
        acx, acy, acz = verts[c, 0] - verts[a, 0], verts[c, 1] - verts[a, 1], verts[c, 2] - verts[a, 2]
        bcx, bcy, bcz = acx - abx, acy - aby, acz - abz
        nx, ny, nz = aby * acz - abz * acy, abz * acx - abx * acz, abx * acy - aby * acx
        ln = math.sqrt(nx * nx + ny * ny + nz * nz)
        if ln > 0.0:
            nx, ny, nz = nx / ln, ny / ln, nz / ln
        tri_normals_out[t, 0], tri_normals_out[t, 1], tri_normals_out[t, 2] = nx, ny, nz
        for corner in range(3):
            if corner == 0:  # the two edges leaving the corner
                v, ux, uy, uz, wx, wy, wz = a, abx, aby, abz, acx, acy, acz
            elif corner == 1:
                v, ux, uy, uz, wx, wy, wz = b, bcx, bcy, bcz, -abx, -aby, -abz
            else:
                v, ux, uy, uz, wx, wy, wz = c, -acx, -acy, -acz, -bcx, -bcy, -bcz
            cx, cy, cz = uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx
            angle = math.atan2(math.sqrt(cx * cx + cy * cy + cz * cz), ux * wx + uy * wy + uz * wz)
            vert_normals_out[v, 0] += angle * nx
            vert_normals_out[v, 1] += angle * ny
            vert_normals_out[v, 2] += angle * nz
            e = tri_edges[t, corner]
            edge_normals_out[e, 0] += nx
            edge_normals_out[e, 1] += ny
            edge_normals_out[e, 2] += nz
    normalise_rows(edge_normals_out)
    normalise_rows(vert_normals_out)


@njit
def normalise_rows(a):
    for r in range(a.shape[0]):
        ln = math.sqrt(a[r, 0] ** 2 + a[r, 1] ** 2 + a[r, 2] ** 2)
        if ln > 0.0:
            a[r, 0], a[r, 1], a[r, 2] = a[r, 0] / ln, a[r, 1] / ln, a[r, 2] / ln


@njit
def triangle_records(verts, tris, tri_data_out):
    """Fill the per-triangle records of :data:`.collide_mesh.BodyGrid` and sum areas and perimeters.

    Parameters
    ----------
    verts : (v, 3) float64, m;  tris : (t, 3) int64
    tri_data_out : (t, 16) float64, m
        Bounding box min xyz, max xyz, corners a, b, c, and a zero pad.

    Returns
    -------
    (float, float)
        Total area (m^2) and total perimeter (m), for the pair-count estimate.
    """
    area = 0.0
    perimeter = 0.0
    for t in range(tris.shape[0]):
        for ax in range(3):
            u, v, w = verts[tris[t, 0], ax], verts[tris[t, 1], ax], verts[tris[t, 2], ax]
            tri_data_out[t, ax], tri_data_out[t, 3 + ax] = min(u, v, w), max(u, v, w)
            tri_data_out[t, 6 + ax], tri_data_out[t, 9 + ax], tri_data_out[t, 12 + ax] = u, v, w
        tri_data_out[t, 15] = 0.0
        d = tri_data_out[t, 6:15]
        ux, uy, uz = d[3] - d[0], d[4] - d[1], d[5] - d[2]
        vx, vy, vz = d[6] - d[0], d[7] - d[1], d[8] - d[2]
        area += 0.5 * math.sqrt((uy * vz - uz * vy) ** 2 + (uz * vx - ux * vz) ** 2 + (ux * vy - uy * vx) ** 2)
        perimeter += (math.sqrt(ux * ux + uy * uy + uz * uz) + math.sqrt(vx * vx + vy * vy + vz * vz)
                      + math.sqrt((vx - ux) ** 2 + (vy - uy) ** 2 + (vz - uz) ** 2))
    return area, perimeter


#: Distance levels of a cell's list: the list is ordered by level, and ``cell_tdist`` holds each
#: triangle's level floor ``level * reach / LEVELS`` (a lower bound: the search's early exit stays exact).
LEVELS = 64


@njit
def _axis_cells(lo, hi, o, n, inv_h):
    """Cells ``[c0, c1]`` (clamped to ``[0, n - 1]``) whose centre ``o + (c + 0.5) h`` lies in ``[lo, hi]``."""
    return max(int(math.ceil((lo - o) * inv_h - 0.5)), 0), min(int(math.floor((hi - o) * inv_h - 0.5)), n - 1)


@njit
def bin_triangles(verts, tris, origin, dims, h, reach, pair_cell_out, pair_tri_out, pair_level_out):
    """Every (cell, triangle) pair with the cell centre within ``reach`` (m) of the triangle.

    Triangle by triangle, only cells in the triangle's bounding sphere grown by ``reach`` and in
    the slab ``|n . (p - a)| <= reach`` are tested (both contain every point within ``reach``;
    the ranges are widened by 1e-7 h against rounding). The distance uses the in-plane edge
    normals ``m_k = e_k x n``: a point with ``m_k . (p - v_k) <= 0`` for all three edges
    projects into the triangle and is at ``|n . (p - a)|``; any other is nearest to the
    boundary, the closest of the three edge segments. Computed for a whole column of cells
    without branches, then kept if ``<= reach``.

    Parameters
    ----------
    verts : (v, 3) float64, m;  tris : (t, 3) int64
    origin : (3,) float64, m;  dims : (3,) int64;  h, reach : float, m
    pair_cell_out, pair_tri_out : (cap,) int32
        Cell and triangle of each pair, in triangle order (int32: the pairs are written and read
        once each, and memory bandwidth is what this build is bound by).
    pair_level_out : (cap,) uint8
        ``floor(LEVELS * distance / reach)``, at most ``LEVELS - 1``. Only the first ``cap``
        pairs are written.

    Returns
    -------
    int
        Number of pairs (rerun with larger outputs if it exceeds ``cap``).
    """
    column = np.empty(dims[2])
    no_stamp = np.empty(0, dtype=np.int32)
    n = 0
    for t in range(tris.shape[0]):
        a, b, c = tris[t, 0], tris[t, 1], tris[t, 2]
        n = bin_triangle(verts[a, 0], verts[a, 1], verts[a, 2], verts[b, 0], verts[b, 1], verts[b, 2],
                         verts[c, 0], verts[c, 1], verts[c, 2], t, origin, dims, h, reach, 0.0, LEVELS / reach,
                         column, no_stamp, no_stamp, pair_cell_out, pair_tri_out, pair_level_out, n)
    return n


@njit(inline="always")
def bin_triangle(ax, ay, az, bx, by, bz, cx, cy, cz, t, origin, dims, h, reach, shift, per_level, column, stamp,
                 slot, pair_cell_out, pair_tri_out, pair_level_out, n):
    """The pairs of triangle ``t`` (corners a, b, c) for :func:`bin_triangles`, appended from pair ``n``;
    returns the new count. A pair's level is that of its distance less ``shift`` (m, at least 0), with
    ``per_level`` levels per metre.

    With ``stamp`` and ``slot`` ((ncells,) int32, non-empty) a cell that already holds a pair of ``t``
    (``stamp[cell] == t``, at ``slot[cell]``) keeps one pair at the lower level: a triangle binned in
    several pieces (:mod:`.collide_mesh_sweep`) is listed once per cell.
    """
    ny_, nz_ = dims[1], dims[2]
    inv_h = 1.0 / h
    r2 = reach * reach
    eps = 1e-7 * h
    cap = pair_cell_out.shape[0]
    dedupe = stamp.shape[0] > 0
    e0x, e0y, e0z = bx - ax, by - ay, bz - az
    e1x, e1y, e1z = cx - bx, cy - by, cz - bz
    e2x, e2y, e2z = ax - cx, ay - cy, az - cz
    nx, ny, nz = e2y * e0z - e2z * e0y, e2z * e0x - e2x * e0z, e2x * e0y - e2y * e0x
    ln = math.sqrt(nx * nx + ny * ny + nz * nz)
    if ln > 0.0:
        nx, ny, nz = nx / ln, ny / ln, nz / ln
    # else a segment or a point: only the edge distances count
    flat = -1.0 if ln > 0.0 else 1.0
    m0x, m0y, m0z = e0y * nz - e0z * ny, e0z * nx - e0x * nz, e0x * ny - e0y * nx
    m1x, m1y, m1z = e1y * nz - e1z * ny, e1z * nx - e1x * nz, e1x * ny - e1y * nx
    m2x, m2y, m2z = e2y * nz - e2z * ny, e2z * nx - e2x * nz, e2x * ny - e2y * nx
    l0 = e0x * e0x + e0y * e0y + e0z * e0z
    l1 = e1x * e1x + e1y * e1y + e1z * e1z
    l2 = e2x * e2x + e2y * e2y + e2z * e2z
    i0 = 1.0 / l0 if l0 > 0.0 else 0.0
    i1 = 1.0 / l1 if l1 > 0.0 else 0.0
    i2 = 1.0 / l2 if l2 > 0.0 else 0.0
    gx, gy, gz = (ax + bx + cx) / 3.0, (ay + by + cy) / 3.0, (az + bz + cz) / 3.0
    rs = reach + eps + math.sqrt(max((ax - gx) ** 2 + (ay - gy) ** 2 + (az - gz) ** 2,
                                     (bx - gx) ** 2 + (by - gy) ** 2 + (bz - gz) ** 2,
                                     (cx - gx) ** 2 + (cy - gy) ** 2 + (cz - gz) ** 2))
    slab = ln > 0.0 and abs(nz) > 1e-3
    inv_nz = 1.0 / nz if slab else 0.0
    # the bounding box grown by reach is tighter than the sphere for a long thin triangle
    ia, ib = _axis_cells(max(gx - rs, min(ax, bx, cx) - reach - eps), min(gx + rs, max(ax, bx, cx) + reach + eps),
                         origin[0], dims[0], inv_h)
    ja, jb = _axis_cells(max(gy - rs, min(ay, by, cy) - reach - eps), min(gy + rs, max(ay, by, cy) + reach + eps),
                         origin[1], dims[1], inv_h)
    zmin, zmax = min(az, bz, cz) - reach - eps, max(az, bz, cz) + reach + eps
    # z parts of the per-cell dot products (the x, y parts are fixed along a column)
    e0zi, e1zi, e2zi = e0z * i0, e1z * i1, e2z * i2
    for i in range(ia, ib + 1):
        px = origin[0] + (i + 0.5) * h
        rem_i = rs * rs - (px - gx) ** 2
        if rem_i < 0.0:
            continue
        wax, wbx, wcx = px - ax, px - bx, px - cx
        for j in range(ja, jb + 1):
            py = origin[1] + (j + 0.5) * h
            rem = rem_i - (py - gy) ** 2
            if rem < 0.0:
                continue
            sxy = nx * wax + ny * (py - ay)
            ka, kb = _column_cells(gz - math.sqrt(rem), gz + math.sqrt(rem), zmin, zmax, slab, az, sxy, inv_nz,
                                   reach + eps, origin[2], nz_, inv_h)
            way, wby, wcy = py - ay, py - by, py - cy
            t0 = (wax * e0x + way * e0y) * i0
            t1 = (wbx * e1x + wby * e1y) * i1
            t2 = (wcx * e2x + wcy * e2y) * i2
            o0, o1, o2 = m0x * wax + m0y * way, m1x * wbx + m1y * wby, m2x * wcx + m2y * wcy
            for k in range(ka, kb + 1):
                pz = origin[2] + (k + 0.5) * h
                waz, wbz, wcz = pz - az, pz - bz, pz - cz
                u = min(max(t0 + waz * e0zi, 0.0), 1.0)
                d0 = (wax - u * e0x) ** 2 + (way - u * e0y) ** 2 + (waz - u * e0z) ** 2
                u = min(max(t1 + wbz * e1zi, 0.0), 1.0)
                d1 = (wbx - u * e1x) ** 2 + (wby - u * e1y) ** 2 + (wbz - u * e1z) ** 2
                u = min(max(t2 + wcz * e2zi, 0.0), 1.0)
                d2 = (wcx - u * e2x) ** 2 + (wcy - u * e2y) ** 2 + (wcz - u * e2z) ** 2
                s = sxy + nz * waz
                o = max(o0 + m0z * waz, o1 + m1z * wbz, o2 + m2z * wcz, flat)
                column[k] = s * s if o <= 0.0 else min(d0, d1, d2)
            base = (i * ny_ + j) * nz_
            for k in range(ka, kb + 1):
                if column[k] <= r2:
                    level = min(int(max(math.sqrt(column[k]) - shift, 0.0) * per_level), LEVELS - 1)
                    cell = base + k
                    if dedupe and stamp[cell] == t:
                        at = slot[cell]
                        if at < cap and level < pair_level_out[at]:
                            pair_level_out[at] = level
                        continue
                    if dedupe:
                        stamp[cell] = t
                        slot[cell] = n
                    if n < cap:
                        pair_cell_out[n] = cell
                        pair_tri_out[n] = t
                        pair_level_out[n] = level
                    n += 1
    return n


@njit(inline="always")  # once per column: a call is measurable
def _column_cells(zlo, zhi, zmin, zmax, slab, az, sxy, inv_nz, r, o, n, inv_h):
    """Cells of a column in ``[zlo, zhi]`` (the sphere), ``[zmin, zmax]`` (the box) and, with ``slab``,
    where ``|sxy + nz (z - az)| <= r`` (the plane's slab, ``inv_nz = 1 / nz``)."""
    zlo, zhi = max(zlo, zmin), min(zhi, zmax)
    if slab:
        z1 = az + (-r - sxy) * inv_nz
        z2 = az + (r - sxy) * inv_nz
        zlo, zhi = max(zlo, min(z1, z2)), min(zhi, max(z1, z2))
    return _axis_cells(zlo, zhi, o, n, inv_h)


@njit
def cell_lists(pair_cell, pair_tri, pair_level, reach, cell_start_out, cell_tris_out, cell_tdist_out, level):
    """Group the pairs of :func:`bin_triangles` by cell, each cell's list ordered by distance level.

    Parameters
    ----------
    pair_cell, pair_tri : (m,) int32;  pair_level : (m,) uint8
    reach : float, m
        The ``reach`` of :func:`bin_triangles`.
    cell_start_out : (ncells + 1,) int64
        CSR offsets.
    cell_tris_out : (m,) int64;  cell_tdist_out : (m,) float64, m
        Each cell's triangles by distance level (in pair order within a level) and the level's
        floor, a lower bound on the triangle's distance to the cell centre.
    level : (m,) uint8
        Scratch.
    """
    ncells = cell_start_out.shape[0] - 1
    cell_start_out[:] = 0
    for s in range(pair_cell.shape[0]):
        cell_start_out[pair_cell[s] + 1] += 1
    # cell_start_out[c + 1] becomes the start of c and, after the stable scatter, its end
    total = 0
    longest = 0
    for c in range(ncells):
        count = cell_start_out[c + 1]
        cell_start_out[c + 1] = total
        total += count
        longest = max(longest, count)
    for s in range(pair_cell.shape[0]):
        slot = cell_start_out[pair_cell[s] + 1]
        cell_tris_out[slot] = pair_tri[s]
        level[slot] = pair_level[s]
        cell_start_out[pair_cell[s] + 1] = slot + 1
    tmp = np.empty(longest, dtype=np.int64)
    counts = np.empty(LEVELS + 1, dtype=np.int64)
    step = reach / LEVELS * (1.0 - 1e-12)  # a floor even where the level was rounded up
    for c in range(ncells):
        a, b = cell_start_out[c], cell_start_out[c + 1]
        if b - a > 16:
            # counting sort by level (stable)
            counts[:] = 0
            for s in range(a, b):
                counts[level[s] + 1] += 1
            for q in range(LEVELS):
                counts[q + 1] += counts[q]
            for s in range(a, b):
                q = level[s]
                tmp[counts[q]] = cell_tris_out[s]
                counts[q] += 1
            for q in range(LEVELS):  # counts[q] is now the end of level q
                lo = counts[q - 1] if q > 0 else 0
                for r in range(lo, counts[q]):
                    cell_tris_out[a + r] = tmp[r]
                    cell_tdist_out[a + r] = q * step
        else:
            # insertion sort by level (stable); short lists are nearly in order already
            for s in range(a + 1, b):
                key, idv = level[s], cell_tris_out[s]
                m = s - 1
                while m >= a and level[m] > key:
                    level[m + 1] = level[m]
                    cell_tris_out[m + 1] = cell_tris_out[m]
                    m -= 1
                level[m + 1] = key
                cell_tris_out[m + 1] = idv
            for s in range(a, b):
                cell_tdist_out[s] = level[s] * step
