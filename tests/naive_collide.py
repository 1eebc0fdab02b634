"""Slow, obvious NumPy references for the mesh collider kernels (tests only).

Every point is compared with every triangle; pseudo-normals are rebuilt here with
plain loops so they do not share code with the implementation.
"""
import numpy as np


def closest_on_triangles(p, a, b, c):
    """Closest point of p (3,) on each triangle (t, 3) x 3 (Ericson 5.1.5, vectorised).

    Returns q (t, 3) and the feature (t,) int: 0 face, 1..3 vertex a, b, c, 4..6 edge ab, bc, ca.
    """
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = np.einsum("ij,ij->i", ab, ap), np.einsum("ij,ij->i", ac, ap)
    bp = p - b
    d3, d4 = np.einsum("ij,ij->i", ab, bp), np.einsum("ij,ij->i", ac, bp)
    cp = p - c
    d5, d6 = np.einsum("ij,ij->i", ab, cp), np.einsum("ij,ij->i", ac, cp)
    vc = d1 * d4 - d3 * d2
    vb = d5 * d2 - d1 * d6
    va = d3 * d6 - d5 * d4
    q = np.empty_like(a)
    f = np.full(a.shape[0], -1)
    done = np.zeros(a.shape[0], dtype=bool)

    def take(mask, value, code):
        m = mask & ~done
        q[m] = value[m] if value.ndim == 2 else value
        f[m] = code
        done[m] = True

    with np.errstate(divide="ignore", invalid="ignore"):
        take((d1 <= 0) & (d2 <= 0), a, 1)
        take((d3 >= 0) & (d4 <= d3), b, 2)
        take((vc <= 0) & (d1 >= 0) & (d3 <= 0), a + (d1 / (d1 - d3))[:, None] * ab, 4)
        take((d6 >= 0) & (d5 <= d6), c, 3)
        take((vb <= 0) & (d2 >= 0) & (d6 <= 0), a + (d2 / (d2 - d6))[:, None] * ac, 6)
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        take((va <= 0) & ((d4 - d3) >= 0) & ((d5 - d6) >= 0), b + w[:, None] * (c - b), 5)
        den = va + vb + vc
        take(np.ones_like(done), a + ab * (vb / den)[:, None] + ac * (vc / den)[:, None], 0)
    return q, f


def pseudo_normals(verts, tris):
    """Face, edge (dict keyed by sorted vertex pair) and vertex pseudo-normals by loops."""
    fn = np.zeros((len(tris), 3))
    vn = np.zeros_like(verts)
    en = {}
    for t, (i, j, k) in enumerate(tris):
        a, b, c = verts[i], verts[j], verts[k]
        n = np.cross(b - a, c - a)
        n = n / np.linalg.norm(n)
        fn[t] = n
        for v, u, w in ((i, b - a, c - a), (j, c - b, a - b), (k, a - c, b - c)):
            cosang = np.dot(u, w) / (np.linalg.norm(u) * np.linalg.norm(w))
            vn[v] += np.arccos(np.clip(cosang, -1, 1)) * n
        for e in ((i, j), (j, k), (k, i)):
            key = tuple(sorted(e))
            en[key] = en.get(key, 0) + n
    vn /= np.linalg.norm(vn, axis=1, keepdims=True)
    en = {key: n / np.linalg.norm(n) for key, n in en.items()}
    return fn, en, vn


def signed_distance(points, verts, tris):
    """Brute-force signed distance (n,), closest point (n, 3) and triangle (n,) of each point."""
    fn, en, vn = pseudo_normals(verts, tris)
    a, b, c = verts[tris[:, 0]], verts[tris[:, 1]], verts[tris[:, 2]]
    d = np.empty(len(points))
    closest = np.empty((len(points), 3))
    tri = np.empty(len(points), dtype=np.int64)
    for n, p in enumerate(points):
        q, f = closest_on_triangles(p, a, b, c)
        dd = np.einsum("ij,ij->i", p - q, p - q)
        t = int(np.argmin(dd))
        code = f[t]
        if code == 0:
            normal = fn[t]
        elif code <= 3:
            normal = vn[tris[t, code - 1]]
        else:
            e = code - 4
            normal = en[tuple(sorted((tris[t, e], tris[t, (e + 1) % 3])))]
        sign = -1.0 if np.dot(p - q[t], normal) < 0 else 1.0
        d[n] = sign * np.sqrt(dd[t])
        closest[n] = q[t]
        tri[n] = t
    return d, closest, tri


def distances_to_triangles(points, verts, tris):
    """Unsigned distance (n, t) of every point to every triangle (closest_on_triangles per point)."""
    a, b, c = verts[tris[:, 0]], verts[tris[:, 1]], verts[tris[:, 2]]
    out = np.empty((len(points), len(tris)))
    for n, p in enumerate(points):
        q, _ = closest_on_triangles(p, a, b, c)
        out[n] = np.sqrt(np.einsum("ij,ij->i", p - q, p - q))
    return out
