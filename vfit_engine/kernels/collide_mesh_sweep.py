"""Numba kernels of the moving body's grid (:class:`vfit_engine.collide.moving_body.MovingBodyCollider`).

The body moves from pose ``v0`` to pose ``v1`` over one interval (an animation frame), every vertex on the
straight line between them. One grid answers exact queries at any time of the interval:

1. :func:`bin_swept`: a triangle is listed in every cell whose centre comes within ``reach`` of it at *some*
   time of the interval. The interval is cut into ``q`` pieces so that no vertex moves more than ``piece`` in
   one; the triangle at a piece's middle, grown by ``reach`` plus half that move, holds every position of the
   piece (a point of a triangle is a convex combination of its corners, so it moves at most as far as they
   do), and each cell keeps the piece whose lower bound on the distance is smallest. A slow triangle (the
   torso) is binned once, a fast one (a swinging foot) along its path, never in a ball round it.
2. :func:`.collide_mesh_build.cell_lists` groups the pairs by cell (unchanged).
3. :func:`carry_signs`: the side of the body each empty cell's centre is on. An empty cell has no surface
   within ``reach`` of its centre during the interval, so its side does not change in it; a cell empty in the
   last interval too keeps its side, the others take it from an empty 6-neighbour (two adjacent empty
   cells share a side: the segment between their centres stays inside them, which no surface touches);
   a cell none reaches is left for an exact query.
4. :func:`pose_records`: the triangles' records at a time of the interval, per substep.

The cached kernels are stamped with the helpers they inline from :mod:`.collide_mesh` and
:mod:`.collide_mesh_build` too: an edit there recompiles them (:mod:`vfit_engine._jit`).
"""
import math

import numpy as np

from vfit_engine._jit import njit
from vfit_engine.kernels.collide_mesh import closest_on_triangle, signed_result
from vfit_engine.kernels.collide_mesh_build import LEVELS, bin_triangle, normalise_rows


@njit
def bin_swept(v0, v1, tris, origin, dims, h, reach, piece, stamp, slot, pair_cell_out, pair_tri_out,
              pair_level_out, tri_move_out):
    """Every (cell, triangle) pair whose cell centre comes within ``reach`` (m) of the triangle while its
    corners move from ``v0`` to ``v1`` (module docstring, step 1).

    Parameters
    ----------
    v0, v1 : (v, 3) float64, m
        The vertices at the interval's start and end.
    tris : (t, 3) int64
    origin : (3,) float64, m;  dims : (3,) int64;  h, reach, piece : float, m
        Grid, band, and the longest move of a vertex within one piece.
    stamp, slot : (ncells,) int32
        Scratch: ``stamp`` must hold no triangle index (e.g. all -1) on entry; it is left so.
    pair_cell_out, pair_tri_out : (cap,) int32;  pair_level_out : (cap,) uint8
        As :func:`.collide_mesh_build.bin_triangles`; the level is that of a lower bound on the distance
        over the whole interval, on ``LEVELS`` levels of ``(reach + piece / 2) / LEVELS``.
    tri_move_out : (t,) float64, m
        The longest move of each triangle's corners over the interval.

    Returns
    -------
    int
        Number of pairs (rerun with larger outputs if it exceeds ``cap``).
    """
    column = np.empty(dims[2])
    per_level = LEVELS / (reach + 0.5 * piece)
    stamp[:] = -1
    no_stamp = stamp[:0]  # one piece: no cell can be met twice, and no stamp need be read
    n = 0
    for t in range(tris.shape[0]):
        a, b, c = tris[t, 0], tris[t, 1], tris[t, 2]
        move = 0.0
        for v in (a, b, c):
            move = max(move, math.sqrt((v1[v, 0] - v0[v, 0]) ** 2 + (v1[v, 1] - v0[v, 1]) ** 2
                                       + (v1[v, 2] - v0[v, 2]) ** 2))
        tri_move_out[t] = move
        q = max(1, int(math.ceil(move / piece)))
        half_move = 0.5 * move / q * (1.0 + 1e-9) + 1e-12  # a little over: the bound stays one
        for j in range(q):
            s = (j + 0.5) / q
            n = bin_triangle(v0[a, 0] + s * (v1[a, 0] - v0[a, 0]), v0[a, 1] + s * (v1[a, 1] - v0[a, 1]),
                             v0[a, 2] + s * (v1[a, 2] - v0[a, 2]), v0[b, 0] + s * (v1[b, 0] - v0[b, 0]),
                             v0[b, 1] + s * (v1[b, 1] - v0[b, 1]), v0[b, 2] + s * (v1[b, 2] - v0[b, 2]),
                             v0[c, 0] + s * (v1[c, 0] - v0[c, 0]), v0[c, 1] + s * (v1[c, 1] - v0[c, 1]),
                             v0[c, 2] + s * (v1[c, 2] - v0[c, 2]), t, origin, dims, h, reach + half_move,
                             half_move, per_level, column, stamp if q > 1 else no_stamp, slot, pair_cell_out,
                             pair_tri_out, pair_level_out, n)
    return n


@njit
def carry_signs(dims, cell_start, was_listed, side, queue):
    """The side (+1 outside, -1 inside) of every empty cell of a new interval (module docstring, step 3).

    Parameters
    ----------
    dims : (3,) int64
    cell_start : (ncells + 1,) int64
        The new interval's lists (empty: ``cell_start[c] == cell_start[c + 1]``).
    was_listed : (ncells,) bool
        The cells listed in the last interval (their ``side`` is stale).
    side : (ncells,) int8
        In: each empty cell's side in the last interval; out: each empty cell's side in the new one, 0 for
        an empty cell no empty neighbour reached (to be queried), anything for listed cells.
    queue : (ncells,) int64
        Scratch.

    Returns
    -------
    int
        The number of empty cells left at 0.
    """
    ncells = side.shape[0]
    todo = 0
    for c in range(ncells):
        if cell_start[c] == cell_start[c + 1] and was_listed[c]:
            side[c] = 0
            todo += 1
    # inside first: a cell marked inside is searched until its closest triangle is found (exact, only slower),
    # one marked outside is dismissed beyond reach; where a side could be either (near a cut of a partial
    # surface), inside is the safe one
    for want in (-1, 1):
        if todo:
            todo -= _flood(dims, cell_start, side, queue, want)
    return todo


@njit
def _flood(dims, cell_start, side, queue, want):
    """Give the empty cells at side 0 reachable from empty cells of side ``want`` that side, breadth first;
    returns how many it gave."""
    nx_, ny_, nz_ = dims[0], dims[1], dims[2]
    slab = ny_ * nz_
    n = 0
    for c in range(side.shape[0]):
        if cell_start[c] != cell_start[c + 1] or side[c] != want:
            continue
        i, j, k = c // slab, (c // nz_) % ny_, c % nz_
        if ((i > 0 and _open(cell_start, side, c - slab)) or (i < nx_ - 1 and _open(cell_start, side, c + slab))
                or (j > 0 and _open(cell_start, side, c - nz_)) or (j < ny_ - 1 and _open(cell_start, side, c + nz_))
                or (k > 0 and _open(cell_start, side, c - 1)) or (k < nz_ - 1 and _open(cell_start, side, c + 1))):
            queue[n] = c
            n += 1
    seeds = n
    head = 0
    while head < n:
        c = queue[head]
        head += 1
        i, j, k = c // slab, (c // nz_) % ny_, c % nz_
        for nb in range(6):
            if nb == 0:
                if i == 0:
                    continue
                d = c - slab
            elif nb == 1:
                if i == nx_ - 1:
                    continue
                d = c + slab
            elif nb == 2:
                if j == 0:
                    continue
                d = c - nz_
            elif nb == 3:
                if j == ny_ - 1:
                    continue
                d = c + nz_
            elif nb == 4:
                if k == 0:
                    continue
                d = c - 1
            else:
                if k == nz_ - 1:
                    continue
                d = c + 1
            if _open(cell_start, side, d):
                side[d] = want
                queue[n] = d
                n += 1
    return n - seeds


@njit(inline="always")
def _open(cell_start, side, c):
    """Cell ``c`` is empty and its side not yet known."""
    return cell_start[c] == cell_start[c + 1] and side[c] == 0


@njit
def cell_bounds(cell_start, side, reach, lo_out, hi_out):
    """Bounds of every cell centre's signed distance over the interval: none for a cell with triangles
    (``-inf`` / ``inf``: the search finds its closest triangle), ``reach`` on its side for an empty one.

    Parameters
    ----------
    cell_start : (ncells + 1,) int64;  side : (ncells,) int8;  reach : float, m
    lo_out, hi_out : (ncells,) float64, m
        :data:`.collide_mesh.BodyGrid`'s ``cell_sd`` and ``cell_sd_hi``.
    """
    for c in range(side.shape[0]):
        if cell_start[c] != cell_start[c + 1]:
            lo_out[c], hi_out[c] = -math.inf, math.inf
        elif side[c] > 0:
            lo_out[c], hi_out[c] = reach, math.inf
        else:
            lo_out[c], hi_out[c] = -math.inf, -reach


@njit
def pose_records(v0, v1, s, verts, tris, verts_out, tri_data_out, f_origin, f_h, field_out):
    """The vertices ``verts`` (k,) at time ``s`` (0..1) of the interval, ``v0 + s (v1 - v0)``, into ``verts_out``
    (v, 3) m, and the triangles' records of :data:`.collide_mesh.BodyGrid` (bounding box, corners) into
    ``tri_data_out`` (t, 16), triangles ``tris`` in the grid's order.

    How far each vertex moved from where ``verts_out`` had it goes into a coarse grid of cells ``f_h`` (m) from
    ``f_origin``: ``field_out`` (fx, fy, fz) holds the largest move of a vertex in each cell (zeroed first).
    Returns the largest move of all (m)."""
    field_out[:] = 0.0
    fx, fy, fz = field_out.shape[0], field_out.shape[1], field_out.shape[2]
    moved = 0.0
    for m in range(verts.shape[0]):
        v = verts[m]
        d2 = 0.0
        for ax in range(3):
            x = v0[v, ax] + s * (v1[v, ax] - v0[v, ax])
            d2 += (x - verts_out[v, ax]) ** 2
            verts_out[v, ax] = x
        d = math.sqrt(d2)
        moved = max(moved, d)
        i = min(max(int((verts_out[v, 0] - f_origin[0]) / f_h), 0), fx - 1)
        j = min(max(int((verts_out[v, 1] - f_origin[1]) / f_h), 0), fy - 1)
        k = min(max(int((verts_out[v, 2] - f_origin[2]) / f_h), 0), fz - 1)
        field_out[i, j, k] = max(field_out[i, j, k], d)
    for t in range(tris.shape[0]):
        for ax in range(3):
            u, w, x = verts_out[tris[t, 0], ax], verts_out[tris[t, 1], ax], verts_out[tris[t, 2], ax]
            tri_data_out[t, ax], tri_data_out[t, 3 + ax] = min(u, w, x), max(u, w, x)
            tri_data_out[t, 6 + ax], tri_data_out[t, 9 + ax], tri_data_out[t, 12 + ax] = u, w, x
    return moved


@njit
def dilate_max(field, out):
    """``out`` (fx, fy, fz): the largest value of ``field`` over each cell and its 26 neighbours."""
    fx, fy, fz = field.shape[0], field.shape[1], field.shape[2]
    for i in range(fx):
        for j in range(fy):
            for k in range(fz):
                top = 0.0
                for a in range(max(i - 1, 0), min(i + 2, fx)):
                    for b in range(max(j - 1, 0), min(j + 2, fy)):
                        for c in range(max(k - 1, 0), min(k + 2, fz)):
                            top = max(top, field[a, b, c])
                out[i, j, k] = top


@njit
def listed_bounds(grid, tri_move, reach, lo_out, hi_out):
    """Bounds over the interval of the centre distances of the listed cells whose centre is within ``reach``
    of the surface at its start (the geometry the grid holds; module docstring of :mod:`vfit_engine.collide.
    moving_body`): with ``sd0`` the exact distance then and ``M`` the longest move of the cell's triangles
    over the interval (``tri_move`` (t,) m, :func:`bin_swept`'s), the distance stays within ``sd0 +- M`` (its
    side kept while ``|sd0| > M``); other cells are left as they are."""
    listed_centre_sd(grid, reach, lo_out, hi_out)
    cell_start, cell_tris = grid.cell_start, grid.cell_tris
    for cc in range(cell_start.shape[0] - 1):
        a, b = cell_start[cc], cell_start[cc + 1]
        if a == b or not (lo_out[cc] == hi_out[cc]):
            continue
        top = 0.0
        for s in range(a, b):
            top = max(top, tri_move[cell_tris[s]])
        top = top * (1.0 + 1e-9) + 1e-12
        sd0 = lo_out[cc]
        if abs(sd0) > top:
            lo_out[cc], hi_out[cc] = sd0 - top, sd0 + top
        else:
            lo_out[cc], hi_out[cc] = -abs(sd0) - top, abs(sd0) + top


@njit
def corner_angles(verts, tris, angles_out):
    """Each triangle corner's angle (rad) into ``angles_out`` (t, 3): the weights of the vertex pseudo-normals
    (:func:`.collide_mesh_build.mesh_normals`), taken once per interval by :func:`pose_normals`."""
    for t in range(tris.shape[0]):
        for k in range(3):
            v, a, b = tris[t, k], tris[t, (k + 1) % 3], tris[t, (k + 2) % 3]
            ux, uy, uz = verts[a, 0] - verts[v, 0], verts[a, 1] - verts[v, 1], verts[a, 2] - verts[v, 2]
            wx, wy, wz = verts[b, 0] - verts[v, 0], verts[b, 1] - verts[v, 1], verts[b, 2] - verts[v, 2]
            cx, cy, cz = uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx
            angles_out[t, k] = math.atan2(math.sqrt(cx * cx + cy * cy + cz * cz), ux * wx + uy * wy + uz * wz)


@njit
def pose_normals(verts, tris, tri_edges, angles, tri_normals_out, edge_normals_out, vert_normals_out):
    """Face normals and the edges' and vertices' pseudo-normals (Baerentzen & Aanaes 2005) of ``tris`` at
    ``verts``, as :func:`.collide_mesh_build.mesh_normals` but with the corner ``angles`` (t, 3) given (from
    the interval's start: a triangle barely changes shape within a frame, and the angles' arc tangents were
    most of the cost). Vertices and edges of no triangle in ``tris`` get zero normals."""
    edge_normals_out[:] = 0.0
    vert_normals_out[:] = 0.0
    for t in range(tris.shape[0]):
        a, b, c = tris[t, 0], tris[t, 1], tris[t, 2]
        abx, aby, abz = verts[b, 0] - verts[a, 0], verts[b, 1] - verts[a, 1], verts[b, 2] - verts[a, 2]
        acx, acy, acz = verts[c, 0] - verts[a, 0], verts[c, 1] - verts[a, 1], verts[c, 2] - verts[a, 2]
        nx, ny, nz = aby * acz - abz * acy, abz * acx - abx * acz, abx * acy - aby * acx
        ln = math.sqrt(nx * nx + ny * ny + nz * nz)
        if ln > 0.0:
            nx, ny, nz = nx / ln, ny / ln, nz / ln
        tri_normals_out[t, 0], tri_normals_out[t, 1], tri_normals_out[t, 2] = nx, ny, nz
        for k in range(3):
            v = tris[t, k]
            w = angles[t, k]
            vert_normals_out[v, 0] += w * nx
            vert_normals_out[v, 1] += w * ny
            vert_normals_out[v, 2] += w * nz
            e = tri_edges[t, k]
            edge_normals_out[e, 0] += nx
            edge_normals_out[e, 1] += ny
            edge_normals_out[e, 2] += nz
    normalise_rows(edge_normals_out)
    normalise_rows(vert_normals_out)


@njit
def listed_centre_sd(grid, reach, lo_out, hi_out):
    """The exact signed distance of every listed cell's centre at the grid's current geometry, into ``lo_out``
    and ``hi_out`` (ncells,) m, where it is at most ``reach``: the closest triangle is then in the cell's list
    (the list holds every triangle within ``reach`` at any time of the interval); the others are left as they
    are. The list is ordered by lower bounds of the distances, so the scan stops at the first bound beyond the
    best found."""
    origin, h = grid.origin, grid.h
    ny_, nz_ = grid.dims[1], grid.dims[2]
    tri_data, cell_start, cell_tris, cell_tdist = grid.tri_data, grid.cell_start, grid.cell_tris, grid.cell_tdist
    for cc in range(cell_start.shape[0] - 1):
        a, b = cell_start[cc], cell_start[cc + 1]
        if a == b:
            continue
        i = cc // (ny_ * nz_)
        j = (cc // nz_) % ny_
        k = cc % nz_
        px, py, pz = origin[0] + (i + 0.5) * h, origin[1] + (j + 0.5) * h, origin[2] + (k + 0.5) * h
        best2, best_t, best_f, bqx, bqy, bqz = reach * reach, -1, -1, np.nan, np.nan, np.nan
        for s in range(a, b):
            if cell_tdist[s] > 0.0 and cell_tdist[s] * cell_tdist[s] >= best2:
                break
            t = cell_tris[s]
            qx, qy, qz, f = closest_on_triangle(px, py, pz, tri_data[t, 6], tri_data[t, 7], tri_data[t, 8],
                                                tri_data[t, 9], tri_data[t, 10], tri_data[t, 11],
                                                tri_data[t, 12], tri_data[t, 13], tri_data[t, 14])
            dd = (px - qx) ** 2 + (py - qy) ** 2 + (pz - qz) ** 2
            if dd <= best2:
                best2, best_t, best_f, bqx, bqy, bqz = dd, t, f, qx, qy, qz
        if best_t >= 0:
            d = signed_result(px, py, pz, bqx, bqy, bqz, best2, best_t, best_f, grid.tris, grid.tri_normals,
                              grid.tri_edges, grid.edge_normals, grid.vert_normals)[0]
            lo_out[cc] = d
            hi_out[cc] = d


@njit
def field_lookup(points, f_origin, f_h, field, outside, out):
    """``out`` (k,): the value of the coarse ``field`` (fx, fy, fz) in the cell of each of ``points`` (k, 3) m
    (cells ``f_h`` from ``f_origin``); ``outside`` for a point off the field."""
    fx, fy, fz = field.shape[0], field.shape[1], field.shape[2]
    for p in range(points.shape[0]):
        i = math.floor((points[p, 0] - f_origin[0]) / f_h)
        j = math.floor((points[p, 1] - f_origin[1]) / f_h)
        k = math.floor((points[p, 2] - f_origin[2]) / f_h)
        if 0 <= i < fx and 0 <= j < fy and 0 <= k < fz:
            out[p] = field[i, j, k]
        else:
            out[p] = outside
