"""Numba kernels for the volume a closed triangle mesh encloses and its gradient (the body's mass).

``V = sum_t a . (b x c) / 6`` over triangles (a, b, c) (divergence theorem; outward winding gives V > 0),
and ``dV/da = (b x c) / 6`` per corner, summed over a vertex's triangles. The sum runs about a nearby
origin ``o`` (the first triangle's first vertex) to keep round-off small; V does not depend on it.
The NumPy reference is :func:`vfit_engine.body.measure.enclosed_volume`.

Importing this module imports numba; only measurement code imports it.
"""
from vfit_engine._jit import njit


@njit
def enclosed_volume(verts, tris):
    """Enclosed volume (m^3).

    verts : (n, 3) float64 C-contiguous, m; tris : (t, 3) int64, outward winding.
    """
    ox, oy, oz = verts[tris[0, 0], 0], verts[tris[0, 0], 1], verts[tris[0, 0], 2]
    total = 0.0
    for t in range(tris.shape[0]):
        i, j, k = tris[t, 0], tris[t, 1], tris[t, 2]
        ax, ay, az = verts[i, 0] - ox, verts[i, 1] - oy, verts[i, 2] - oz
        bx, by, bz = verts[j, 0] - ox, verts[j, 1] - oy, verts[j, 2] - oz
        cx, cy, cz = verts[k, 0] - ox, verts[k, 1] - oy, verts[k, 2] - oz
        total += ax * (by * cz - bz * cy) + ay * (bz * cx - bx * cz) + az * (bx * cy - by * cx)
    return total / 6.0


@njit
def volume_gradient(verts, tris, grad_out):
    """dV/dv (m^3 per m) of every vertex into ``grad_out`` ((n, 3) float64, overwritten).

    Uses the origin-free corner terms (b x c) / 6, (c x a) / 6, (a x b) / 6: their sums over a closed
    mesh are the gradient of V whatever the origin.
    """
    grad_out[:] = 0.0
    for t in range(tris.shape[0]):
        i, j, k = tris[t, 0], tris[t, 1], tris[t, 2]
        for c in range(3):
            c1, c2 = (c + 1) % 3, (c + 2) % 3
            grad_out[i, c] += (verts[j, c1] * verts[k, c2] - verts[j, c2] * verts[k, c1]) / 6.0
            grad_out[j, c] += (verts[k, c1] * verts[i, c2] - verts[k, c2] * verts[i, c1]) / 6.0
            grad_out[k, c] += (verts[i, c1] * verts[j, c2] - verts[i, c2] * verts[j, c1]) / 6.0
