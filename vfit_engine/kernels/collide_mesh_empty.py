"""Numba kernels for the empty cells of the body-mesh grid (:data:`.collide_mesh.BodyGrid`).

A cell without triangles is farther than ``margin + h*sqrt(3)/2`` from the surface; its
``cell_sd`` needs a sign and a lower bound on the distance (the search dismisses points in
cells proven beyond the requested band). :func:`empty_cell_sd` computes both from scratch (a
sign per connected empty region, an exact Euclidean distance transform for the bound);
:func:`loosen_empty_sd` derives them from an earlier pose for :meth:`MeshCollider.refit
<vfit_engine.collide.body_mesh.MeshCollider.refit>`.

``scipy.ndimage`` (``label`` + ``distance_transform_edt``) took 90 ms on hm08's 0.89 M cells and
the votes in NumPy another 30 ms; these kernels take ~35 ms, and their scratch comes from the
caller (first touches of fresh memory are costly on the benchmark machine).

Numba's cache watches only this file (nothing here inlines helpers from elsewhere).
"""
import math

import numpy as np

from vfit_engine._jit import njit


@njit
def empty_cell_sd(dims, h, margin, cell_start, cell_sd, band, label, parent, d2):
    """Signed-distance bounds of the cells without triangles, written into ``cell_sd`` (ncells,) m.

    Every point of an empty cell is farther than ``margin`` from the surface, so a connected
    (6-neighbour) region of empty cells lies on one side: its sign is the majority sign of the
    listed cells' centres next to it (exact, already in ``cell_sd``; ties count as outside). The
    regions come from one raster pass with union-find (two-pass connected-component labelling).
    The surface lies in listed cells, so an empty centre is at least (distance to the nearest
    listed centre) - h*sqrt(3)/2 from it, and never less than ``margin + h*sqrt(3)/2``; that
    distance is an exact Euclidean distance transform (Felzenszwalb & Huttenlocher 2012,
    "Distance transforms of sampled functions", one axis at a time).

    Parameters
    ----------
    dims : (3,) int64;  h, margin : float, m
    cell_start : (ncells + 1,) int64
        Listed cells have ``cell_start[c] < cell_start[c + 1]``.
    cell_sd : (ncells,) float64, m
        In: the listed cells' centre distances; out: every cell's.
    band : (ncells,) uint8;  label, parent : (ncells,) int32;  d2 : (ncells,) float64
        Scratch (int32: the build's scratch is kept small, as first touches of fresh memory
        are a good part of it).
    """
    nx_, ny_, nz_ = dims[0], dims[1], dims[2]
    ncells = nx_ * ny_ * nz_
    for c in range(ncells):
        band[c] = cell_start[c] < cell_start[c + 1]
    labels = _label_regions(dims, band, label, parent)
    # votes per provisional label, summed into the roots
    votes = np.zeros(labels)
    slab = ny_ * nz_
    for c in range(ncells):
        if band[c]:
            continue
        i, j, k = c // slab, (c // nz_) % ny_, c % nz_
        v = 0.0
        if i > 0 and band[c - slab]:
            v += np.sign(cell_sd[c - slab])
        if i < nx_ - 1 and band[c + slab]:
            v += np.sign(cell_sd[c + slab])
        if j > 0 and band[c - nz_]:
            v += np.sign(cell_sd[c - nz_])
        if j < ny_ - 1 and band[c + nz_]:
            v += np.sign(cell_sd[c + nz_])
        if k > 0 and band[c - 1]:
            v += np.sign(cell_sd[c - 1])
        if k < nz_ - 1 and band[c + 1]:
            v += np.sign(cell_sd[c + 1])
        votes[label[c]] += v
    for q in range(labels):
        r = _root(parent, q)
        if r != q:
            votes[r] += votes[q]
    sign = np.empty(labels)
    for q in range(labels):
        sign[q] = -1.0 if votes[_root(parent, q)] < 0.0 else 1.0
    _band_distance2(dims, band, d2)
    half = 0.5 * math.sqrt(3.0) * h
    floor = margin + half
    for c in range(ncells):
        if not band[c]:
            cell_sd[c] = sign[label[c]] * max(floor, h * math.sqrt(d2[c]) - half)


@njit
def loosen_empty_sd(cell_start, sd_ref, delta, floor, cell_sd):
    """Bounds of the empty cells after the surface moved by at most ``delta`` (m) since ``sd_ref``.

    A signed distance changes by at most ``delta`` when no surface point moves farther, and a
    centre more than ``delta`` from the old surface keeps its side; an empty cell is more than
    ``floor`` (m, ``margin + h*sqrt(3)/2``) from the surface. So the cell gets
    ``sign(sd_ref) * max(floor, |sd_ref| - delta)``, valid while ``2 delta <= floor``: an empty
    cell was then more than ``floor - delta >= delta`` from the old surface.

    Parameters
    ----------
    cell_start : (ncells + 1,) int64
        The new lists (empty cells: ``cell_start[c] == cell_start[c + 1]``).
    sd_ref : (ncells,) float64, m
        Every cell's value from the last exact computation, same grid.
    delta, floor : float, m
    cell_sd : (ncells,) float64, m
        Written for the empty cells only.
    """
    for c in range(cell_sd.shape[0]):
        if cell_start[c] == cell_start[c + 1]:
            s = sd_ref[c]
            cell_sd[c] = math.copysign(max(floor, abs(s) - delta), s)


@njit(inline="always")  # a call per element would cost reference counting
def _root(parent, q):
    while parent[q] != q:
        parent[q] = parent[parent[q]]  # path halving
        q = parent[q]
    return q


@njit
def _label_regions(dims, band, label_out, parent_out):
    """Provisional labels of the 6-connected regions of ``band == 0`` (one raster pass, union-find).

    ``label_out[c]`` is the provisional label of empty cell c; ``_root(parent_out, label)`` its
    region. Returns the number of provisional labels.
    """
    nx_, ny_, nz_ = dims[0], dims[1], dims[2]
    slab = ny_ * nz_
    labels = 0
    c = 0
    for i in range(nx_):
        for j in range(ny_):
            for k in range(nz_):
                if band[c]:
                    c += 1
                    continue
                lab = -1
                for nb in range(3):
                    if nb == 0:
                        if i == 0 or band[c - slab]:
                            continue
                        other = label_out[c - slab]
                    elif nb == 1:
                        if j == 0 or band[c - nz_]:
                            continue
                        other = label_out[c - nz_]
                    else:
                        if k == 0 or band[c - 1]:
                            continue
                        other = label_out[c - 1]
                    other = _root(parent_out, other)
                    if lab < 0:
                        lab = other
                    elif other != lab:
                        lo, hi = min(lab, other), max(lab, other)
                        parent_out[hi] = lo
                        lab = lo
                if lab < 0:
                    lab = labels
                    parent_out[lab] = lab
                    labels += 1
                label_out[c] = lab
                c += 1
    return labels


@njit
def _band_distance2(dims, band, d2_out):
    """Squared distance (cells^2) from every cell to the nearest cell with ``band`` set (inf if none)."""
    nx_, ny_, nz_ = dims[0], dims[1], dims[2]
    n = max(nx_, ny_, nz_)
    f, out = np.empty(n), np.empty(n)
    v, z = np.empty(n, dtype=np.int64), np.empty(n + 1)
    for line in range(nx_ * ny_):
        base = line * nz_
        # along k: the distance to the nearest band cell of the line, both ways
        last = -1
        for k in range(nz_):
            if band[base + k]:
                last = k
            d2_out[base + k] = (k - last) ** 2 if last >= 0 else np.inf
        last = -1
        for k in range(nz_ - 1, -1, -1):
            if band[base + k]:
                last = k
            elif last >= 0:
                d2_out[base + k] = min(d2_out[base + k], (last - k) ** 2)
    for i in range(nx_):
        for k in range(nz_):
            base = i * ny_ * nz_ + k
            for j in range(ny_):
                f[j] = d2_out[base + j * nz_]
            _dt_line(f, ny_, out, v, z)
            for j in range(ny_):
                d2_out[base + j * nz_] = out[j]
    for j in range(ny_):
        for k in range(nz_):
            base = j * nz_ + k
            for i in range(nx_):
                f[i] = d2_out[base + i * ny_ * nz_]
            _dt_line(f, nx_, out, v, z)
            for i in range(nx_):
                d2_out[base + i * ny_ * nz_] = out[i]


@njit
def _dt_line(f, n, out, v, z):
    """``out[q] = min_p f[p] + (q - p)^2`` over ``p < n`` (lower envelope of parabolas; inf where all f are)."""
    k = -1
    for q in range(n):
        if f[q] == np.inf:
            continue
        if k < 0:
            k = 0
            v[0], z[0], z[1] = q, -np.inf, np.inf
            continue
        while True:
            p = v[k]
            s = ((f[q] + q * q) - (f[p] + p * p)) / (2.0 * (q - p))
            if s > z[k]:
                break
            k -= 1  # z[0] = -inf stops this at k = 0
        k += 1
        v[k], z[k], z[k + 1] = q, s, np.inf
    if k < 0:
        out[:n] = np.inf
        return
    k = 0
    for q in range(n):
        while z[k + 1] < q:
            k += 1
        p = v[k]
        out[q] = (q - p) * (q - p) + f[p]
