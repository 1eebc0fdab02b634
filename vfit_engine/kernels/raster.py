"""Numba z-buffer triangle rasterizer for preview pictures.

The caller projects the vertices (orthographic: a rotation and a scale, see
:mod:`vfit_engine.preview`) into pixel coordinates: ``x`` to the right, ``y`` down, pixel
``(row, col)`` covering ``[col, col + 1) x [row, row + 1)`` with its sample at the centre
``(col + 0.5, row + 0.5)``. Depth is the view-space coordinate towards the viewer, in metres:
larger is nearer. It is kept in float64, so cloth 1 mm off the skin is resolved exactly as far
as the geometry is, and skin that pokes through the cloth shows.

Coverage follows the top-left fill rule (as Direct3D and OpenGL do): a sample exactly on an
edge belongs to the triangle for which that edge is a top or a left edge, so two triangles
sharing an edge cover every sample on it exactly once: no cracks (which would show the body
through closed cloth) and no double hits. Each edge function is evaluated from its
endpoints in vertex-index order and negated when needed, so the two triangles sharing an edge
compute bit-for-bit opposite values. Triangles are two-sided (garments are open surfaces).

Importing this module imports numba; only :mod:`vfit_engine.preview` imports it.
"""
import math

import numpy as np

from vfit_engine._jit import njit


@njit
def _edge_coeffs(xy, ia, ib):
    """Coefficients ``(a, b, c)`` of the edge function ``E(p) = a px + b py + c`` of edge ia -> ib.

    ``E > 0`` on the left of ia -> ib in a y-down frame (inside a triangle of positive area).
    Computed from the endpoint with the smaller index so that ib -> ia gives exactly ``-E``.
    """
    if ia < ib:
        i, j, sign = ia, ib, 1.0
    else:
        i, j, sign = ib, ia, -1.0
    a = -(xy[j, 1] - xy[i, 1])
    b = xy[j, 0] - xy[i, 0]
    c = -(a * xy[i, 0] + b * xy[i, 1])
    return sign * a, sign * b, sign * c


@njit
def _owns_zero(xy, ia, ib):
    """Top-left rule: does a sample exactly on edge ia -> ib (of a positive triangle) belong to it?

    In a y-down frame with positive area, a left edge goes up (dy < 0) and a top edge is
    horizontal going right (dy == 0, dx > 0).
    """
    dy = xy[ib, 1] - xy[ia, 1]
    dx = xy[ib, 0] - xy[ia, 0]
    return dy < 0.0 or (dy == 0.0 and dx > 0.0)


@njit
def _inside(e, owns):
    """Sample inside an edge: strictly, or exactly on it when the edge owns its samples."""
    return e > 0.0 or (e == 0.0 and owns)


@njit
def _clip_span(a, rest, lo, hi):
    """Narrow a row's columns ``lo..hi`` to those whose samples may satisfy ``a (c + 0.5) + rest >= 0``.

    One column of slack is left on the clipped side; the exact test of every sample follows, so
    this only skips samples that are certainly outside (about half of a triangle's bounding box).
    """
    if a == 0.0:
        return lo, hi
    x = -rest / a - 0.5  # the column where the edge crosses the row
    if a > 0.0:
        if x > lo:
            lo = int(math.floor(min(x, hi + 1.0)))
    elif x < hi:
        hi = int(math.ceil(max(x, lo - 1.0)))
    return lo, hi


@njit
def rasterize(xyz, tris, colours, tri_gain, image_out, depth_out):
    """Draw triangles into an image and a depth buffer with a per-sample depth test.

    For each sample ``p`` inside a triangle (top-left rule) the barycentric weights are
    ``w_k = E_k(p) / (2 A)`` (``E_k`` the edge function of the edge opposite vertex ``k``,
    ``2 A`` twice the signed area), the depth ``z = sum w_k z_k`` (exact for an orthographic
    projection) and the colour ``tri_gain[t] * sum w_k colours[k]`` (Gouraud interpolation;
    flat shading passes unshaded vertex colours and the face's shade as ``tri_gain``). The
    sample is written only when ``z > depth_out`` there (plain z-buffer: on an exact tie the
    triangle drawn first stays).

    Parameters
    ----------
    xyz : (n, 3) float64
        Projected vertices: pixel x (right), pixel y (down), depth in metres (larger is nearer).
    tris : (m, 3) int64
        Vertex indices of each triangle; either winding.
    colours : (n, 3) float64
        Linear RGB in [0, 1] of every vertex (already shaded for Gouraud shading).
    tri_gain : (m,) float64
        Factor applied to the interpolated colour of each triangle (flat shade, or 1).
    image_out : (h, w, 3) float64
        Written where a triangle wins the depth test; elsewhere left as it was (see
        :func:`downsample` for the background).
    depth_out : (h, w) float64
        Depth buffer, in and out; the caller initialises it to ``-inf``.
    """
    h, w = depth_out.shape
    for t in range(tris.shape[0]):
        i0, i1, i2 = tris[t, 0], tris[t, 1], tris[t, 2]
        x0, y0 = xyz[i0, 0], xyz[i0, 1]
        area2 = (xyz[i1, 0] - x0) * (xyz[i2, 1] - y0) - (xyz[i1, 1] - y0) * (xyz[i2, 0] - x0)
        if not area2 != 0.0:  # degenerate (or NaN): covers no sample
            continue
        if area2 < 0.0:
            i1, i2 = i2, i1
            area2 = -area2
        xmin = min(x0, xyz[i1, 0], xyz[i2, 0])
        xmax = max(x0, xyz[i1, 0], xyz[i2, 0])
        ymin = min(y0, xyz[i1, 1], xyz[i2, 1])
        ymax = max(y0, xyz[i1, 1], xyz[i2, 1])
        # samples at col + 0.5 within [xmin, xmax]
        c0 = max(int(math.ceil(xmin - 0.5)), 0)
        c1 = min(int(math.floor(xmax - 0.5)), w - 1)
        r0 = max(int(math.ceil(ymin - 0.5)), 0)
        r1 = min(int(math.floor(ymax - 0.5)), h - 1)
        if c0 > c1 or r0 > r1:
            continue
        # edge k is opposite vertex k
        a0, b0, k0 = _edge_coeffs(xyz, i1, i2)
        a1, b1, k1 = _edge_coeffs(xyz, i2, i0)
        a2, b2, k2 = _edge_coeffs(xyz, i0, i1)
        o0 = _owns_zero(xyz, i1, i2)
        o1 = _owns_zero(xyz, i2, i0)
        o2 = _owns_zero(xyz, i0, i1)
        inv = 1.0 / area2
        gain = tri_gain[t]
        for r in range(r0, r1 + 1):
            py = r + 0.5
            lo, hi = _clip_span(a0, b0 * py + k0, c0, c1)
            lo, hi = _clip_span(a1, b1 * py + k1, lo, hi)
            lo, hi = _clip_span(a2, b2 * py + k2, lo, hi)
            for c in range(lo, hi + 1):
                px = c + 0.5
                e0 = a0 * px + b0 * py + k0
                e1 = a1 * px + b1 * py + k1
                e2 = a2 * px + b2 * py + k2
                if not (_inside(e0, o0) and _inside(e1, o1) and _inside(e2, o2)):
                    continue
                w0, w1, w2 = e0 * inv, e1 * inv, e2 * inv
                z = w0 * xyz[i0, 2] + w1 * xyz[i1, 2] + w2 * xyz[i2, 2]
                if z > depth_out[r, c]:
                    depth_out[r, c] = z
                    for k in range(3):
                        image_out[r, c, k] = gain * (w0 * colours[i0, k] + w1 * colours[i1, k]
                                                     + w2 * colours[i2, k])


@njit
def downsample(image, depth, background, factor, out):
    """Box-filter samples to pixels: ``out[r, c]`` is the mean of the ``f x f`` samples it covers.

    A sample no triangle reached (``depth == -inf``) counts as ``background``, so the caller
    clears only the depth buffer between pictures, not the image.

    Parameters
    ----------
    image : (h f, w f, 3) float64
        Samples as written by :func:`rasterize`.
    depth : (h f, w f) float64
        The depth buffer of the same samples.
    background : (3,) float64
        sRGB of empty samples.
    factor : int
        ``f``, samples per pixel along each axis.
    out : (h, w, 3) float64
        Written.
    """
    inv = 1.0 / (factor * factor)
    for r in range(out.shape[0]):
        for c in range(out.shape[1]):
            red = green = blue = 0.0
            for i in range(r * factor, (r + 1) * factor):
                for j in range(c * factor, (c + 1) * factor):
                    if depth[i, j] == -np.inf:
                        red += background[0]
                        green += background[1]
                        blue += background[2]
                    else:
                        red += image[i, j, 0]
                        green += image[i, j, 1]
                        blue += image[i, j, 2]
            out[r, c, 0] = red * inv
            out[r, c, 1] = green * inv
            out[r, c, 2] = blue * inv
