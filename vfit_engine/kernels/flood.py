"""Numba kernels for voxel region growing: voxelisation, multi-source BFS, stack and span flood fills.

Voxel grids are flat C-order ``uint8`` arrays of shape ``(nx, ny, nz)``: voxel ``(i, j, k)`` is
``(i * ny + j) * nz + k`` and its centre is ``origin + (i + 0.5, j + 0.5, k + 0.5) * h``. Callers keep
a border of empty voxels around the solid, so the 6 neighbours of a solid voxel are always inside
the grid and the kernels need no bounds checks.

Counters returned by the fills, used to compare them (same filled set, different work):

* ``visits``: voxel tests (a read of ``solid``/``filled`` deciding whether a voxel is filled);
* ``pushes``: stack pushes;
* ``peak``: largest stack size.
"""
import numpy as np

from vfit_engine._jit import njit


@njit
def voxelise_y(verts, tris, x0, y0, z0, h, nx, ny, nz, solid_out):
    """Solid voxels inside a closed triangle mesh by ray parity along +Y (one ray per column).

    The ray of column ``(i, k)`` runs through ``x = x0 + (i + 0.5) h``, ``z = z0 + (k + 0.5) h``; it
    crosses every triangle whose XZ projection contains that point (edge functions, ties broken by
    the top-left rule so a ray through a shared edge counts once) at the height interpolated
    barycentrically. Voxel ``(i, j, k)`` is solid when its centre lies between crossings ``2m`` and
    ``2m + 1`` of the sorted list (even-odd rule, Nooruddin & Turk 2003 use the same parity per
    axis). A column with an odd number of crossings (an open mesh) loses its last crossing.

    Parameters
    ----------
    verts : (n, 3) float64, m
    tris : (T, 3) int64
    x0, y0, z0, h : float
        Grid origin and voxel size, m.
    nx, ny, nz : int
    solid_out : (nx * ny * nz,) uint8
        Set to 1 inside, 0 outside.

    Returns
    -------
    int
        Number of columns with an odd crossing count.
    """
    ncol = nx * nz
    count = np.zeros(ncol + 1, dtype=np.int64)
    for p in range(2):
        if p == 1:
            # prefix sums: count[c] becomes the start of column c's crossings
            total = 0
            for c in range(ncol):
                n = count[c]
                count[c] = total
                total += n
            count[ncol] = total
            hits = np.empty(total, dtype=np.float64)
            fill = count[:ncol].copy()
        for t in range(tris.shape[0]):
            a = tris[t, 0]
            b = tris[t, 1]
            c3 = tris[t, 2]
            ax, az = verts[a, 0], verts[a, 2]
            bx, bz = verts[b, 0], verts[b, 2]
            cx, cz = verts[c3, 0], verts[c3, 2]
            ay, by, cy = verts[a, 1], verts[b, 1], verts[c3, 1]
            area = (bx - ax) * (cz - az) - (bz - az) * (cx - ax)
            if area == 0.0:
                continue
            if area < 0.0:  # orient counter-clockwise in (x, z) so the tie rule is consistent
                bx, bz, by, cx, cz, cy = cx, cz, cy, bx, bz, by
                area = -area
            i_lo = max(int(np.floor((min(ax, bx, cx) - x0) / h - 0.5)), 0)
            i_hi = min(int(np.ceil((max(ax, bx, cx) - x0) / h - 0.5)), nx - 1)
            k_lo = max(int(np.floor((min(az, bz, cz) - z0) / h - 0.5)), 0)
            k_hi = min(int(np.ceil((max(az, bz, cz) - z0) / h - 0.5)), nz - 1)
            for i in range(i_lo, i_hi + 1):
                px = x0 + (i + 0.5) * h
                for k in range(k_lo, k_hi + 1):
                    pz = z0 + (k + 0.5) * h
                    w0 = (cx - bx) * (pz - bz) - (cz - bz) * (px - bx)
                    w1 = (ax - cx) * (pz - cz) - (az - cz) * (px - cx)
                    w2 = (bx - ax) * (pz - az) - (bz - az) * (px - ax)
                    if not (_inside(w0, bx, bz, cx, cz) and _inside(w1, cx, cz, ax, az)
                            and _inside(w2, ax, az, bx, bz)):
                        continue
                    col = i * nz + k
                    if p == 0:
                        count[col] += 1
                    else:
                        hits[fill[col]] = (w0 * ay + w1 * by + w2 * cy) / area
                        fill[col] += 1
    odd = 0
    for c in range(ncol):
        s, e = count[c], count[c + 1]
        # insertion sort: a column has a handful of crossings
        for m in range(s + 1, e):
            v = hits[m]
            q = m - 1
            while q >= s and hits[q] > v:
                hits[q + 1] = hits[q]
                q -= 1
            hits[q + 1] = v
        if (e - s) % 2 == 1:
            odd += 1
            e -= 1
        i = c // nz
        k = c - i * nz
        base = i * ny * nz + k
        for j in range(ny):
            solid_out[base + j * nz] = 0
        for m in range(s, e, 2):
            j_lo = max(int(np.ceil((hits[m] - y0) / h - 0.5)), 0)
            j_hi = min(int(np.floor((hits[m + 1] - y0) / h - 0.5)), ny - 1)
            for j in range(j_lo, j_hi + 1):
                solid_out[base + j * nz] = 1
    return odd


@njit
def _inside(w, ax, az, bx, bz):
    """Edge test with the top-left tie rule: a point on the edge a->b counts for one side only."""
    if w > 0.0:
        return True
    if w < 0.0:
        return False
    return (bz - az) > 0.0 or ((bz - az) == 0.0 and (bx - ax) < 0.0)


@njit
def multi_source_bfs(solid, nx, ny, nz, seeds, seed_labels, seed_delays, labels_out, dist_out):
    """Grow all regions at once: each solid voxel takes the label of its nearest seed.

    Breadth-first search from all seeds together over 6-connected solid voxels (a FIFO queue
    processes voxels in order of non-decreasing distance, so the first wave to reach a voxel comes
    from a nearest seed in geodesic voxel steps, the L1 metric inside the solid). A seed enters the
    search ``seed_delays[s]`` steps late, which shifts its region's boundaries towards it; seeds must
    come sorted by delay. Ties go to the seed listed first.

    Parameters
    ----------
    solid : (N,) uint8
    nx, ny, nz : int
    seeds : (s,) int64
        Flat voxel index of each seed (solid voxels).
    seed_labels : (s,) int64
    seed_delays : (s,) int64
        Start distance of each seed, non-decreasing.
    labels_out : (N,) int64
        Label of every reached voxel, -1 elsewhere.
    dist_out : (N,) int64
        Geodesic voxel distance (plus delay), -1 where unreached.

    Returns
    -------
    int
        Voxel tests made (neighbour reads).
    """
    n = solid.shape[0]
    for v in range(n):
        labels_out[v] = -1
        dist_out[v] = -1
    queue = np.empty(n, dtype=np.int64)
    offs = np.array([1, -1, nz, -nz, ny * nz, -ny * nz], dtype=np.int64)
    head = 0
    tail = 0
    s = 0
    ns = seeds.shape[0]
    visits = 0
    while True:
        # inject seeds whose delay has come: when the head first holds distance d the queue holds
        # only distance-d voxels, so appending delay-d seeds keeps it sorted
        while s < ns and (head == tail or seed_delays[s] <= dist_out[queue[head]]):
            v = seeds[s]
            if labels_out[v] < 0:
                labels_out[v] = seed_labels[s]
                dist_out[v] = seed_delays[s]
                queue[tail] = v
                tail += 1
            s += 1
        if head == tail:
            break
        v = queue[head]
        head += 1
        for m in range(6):
            u = v + offs[m]
            visits += 1
            if solid[u] != 0 and labels_out[u] < 0:
                labels_out[u] = labels_out[v]
                dist_out[u] = dist_out[v] + 1
                queue[tail] = u
                tail += 1
    return visits


@njit
def flood_fill_stack(solid, nx, ny, nz, seed, filled_out):
    """Plain 6-connected stack flood fill of the region of one voxel.

    Marks a voxel visited when it is pushed, so each is pushed at most once; every pop tests its 6
    neighbours. A 2-D image is one ``i`` layer between two empty ones: the out-of-plane neighbours
    are then empty and the fill is the 4-connected one.

    Parameters
    ----------
    solid : (N,) uint8
    nx, ny, nz : int
    seed : int
        Flat index of a solid voxel.
    filled_out : (N,) uint8
        Set to 1 on the filled voxels (must be zero on entry).

    Returns
    -------
    (visits, pushes, peak) : (int, int, int)
    """
    n = solid.shape[0]
    stack = np.empty(n, dtype=np.int64)
    offs = np.array([1, -1, nz, -nz, ny * nz, -ny * nz], dtype=np.int64)
    top = 0
    visits = 1
    pushes = 0
    peak = 0
    if solid[seed] == 0:
        return visits, pushes, peak
    filled_out[seed] = 1
    stack[top] = seed
    top += 1
    pushes += 1
    peak = 1
    while top > 0:
        top -= 1
        v = stack[top]
        for m in range(6):
            u = v + offs[m]
            visits += 1
            if solid[u] != 0 and filled_out[u] == 0:
                filled_out[u] = 1
                stack[top] = u
                top += 1
                pushes += 1
        if top > peak:
            peak = top
    return visits, pushes, peak


@njit
def flood_fill_span(solid, nx, ny, nz, seed, filled_out):
    """Span (scan-line) flood fill of the 6-connected region of one voxel.

    A popped voxel is extended to its whole run along Z (the fastest-varying axis), which is
    filled; the four neighbouring lines (j +- 1, i +- 1) are then scanned over the run's extent and
    one seed is pushed per maximal unfilled solid stretch (Heckbert 1990, "A seed fill algorithm",
    Graphics Gems; Smith 1979's span fill in 3-D). Fills the same set as :func:`flood_fill_stack`
    with one push per span instead of one per voxel.

    Parameters
    ----------
    solid : (N,) uint8
    nx, ny, nz : int
    seed : int
    filled_out : (N,) uint8
        Set to 1 on the filled voxels (must be zero on entry).

    Returns
    -------
    (visits, pushes, peak) : (int, int, int)
    """
    n = solid.shape[0]
    stack = np.empty(n, dtype=np.int64)
    lines = np.array([nz, -nz, ny * nz, -ny * nz], dtype=np.int64)
    top = 0
    visits = 1
    pushes = 0
    peak = 0
    if solid[seed] == 0:
        return visits, pushes, peak
    stack[top] = seed
    top += 1
    pushes += 1
    peak = 1
    while top > 0:
        top -= 1
        v = stack[top]
        visits += 1
        if filled_out[v] != 0:  # filled by another span after it was pushed
            continue
        lo = v
        while True:
            visits += 1
            if solid[lo - 1] != 0 and filled_out[lo - 1] == 0:
                lo -= 1
            else:
                break
        hi = v
        while True:
            visits += 1
            if solid[hi + 1] != 0 and filled_out[hi + 1] == 0:
                hi += 1
            else:
                break
        for w in range(lo, hi + 1):
            filled_out[w] = 1
        for m in range(4):
            d = lines[m]
            in_run = False
            for w in range(lo + d, hi + d + 1):
                visits += 1
                if solid[w] != 0 and filled_out[w] == 0:
                    if not in_run:
                        stack[top] = w
                        top += 1
                        pushes += 1
                        in_run = True
                else:
                    in_run = False
        if top > peak:
            peak = top
    return visits, pushes, peak


@njit
def nearest_solid(points, x0, y0, z0, h, solid, nx, ny, nz, max_radius, index_out):
    """Flat index of the solid voxel whose centre is nearest to each point.

    Searches cubical shells of growing Chebyshev radius ``r`` around the point's voxel and stops
    once ``(r - 0.5) h`` (the least distance from the point to a centre of shell ``r``) exceeds the
    best distance found, so the answer is exact.

    Parameters
    ----------
    points : (p, 3) float64, m
    x0, y0, z0, h : float
        Grid origin and voxel size, m.
    solid : (N,) uint8
    nx, ny, nz, max_radius : int
    index_out : (p,) int64
        Nearest solid voxel, -1 if none within ``max_radius`` voxels.
    """
    for p in range(points.shape[0]):
        ci = int(np.floor((points[p, 0] - x0) / h))
        cj = int(np.floor((points[p, 1] - y0) / h))
        ck = int(np.floor((points[p, 2] - z0) / h))
        best = -1
        best_d = np.inf
        for r in range(max_radius + 1):
            if best >= 0 and (r - 0.5) * h > np.sqrt(best_d):
                break
            for i in range(max(ci - r, 0), min(ci + r, nx - 1) + 1):
                for j in range(max(cj - r, 0), min(cj + r, ny - 1) + 1):
                    for k in range(max(ck - r, 0), min(ck + r, nz - 1) + 1):
                        # only the shell of this radius: inner cubes were searched already
                        if max(abs(i - ci), abs(j - cj), abs(k - ck)) != r:
                            continue
                        v = (i * ny + j) * nz + k
                        if solid[v] == 0:
                            continue
                        dx = x0 + (i + 0.5) * h - points[p, 0]
                        dy = y0 + (j + 0.5) * h - points[p, 1]
                        dz = z0 + (k + 0.5) * h - points[p, 2]
                        d = dx * dx + dy * dy + dz * dz
                        if d < best_d:
                            best_d = d
                            best = v
        index_out[p] = best
