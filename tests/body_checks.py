"""Independent checks that a body stays a body: faces that turned over, and parts that went into each other.

Plain NumPy plus trimesh's plane sections; nothing from vfit's measurement code.
"""
import numpy as np
import trimesh


def face_normals(verts, tris):
    """(t, 3) unit normals of the triangles."""
    a, b, c = (verts[tris[:, k]] for k in range(3))
    n = np.cross(b - a, c - a)
    return n / np.maximum(np.linalg.norm(n, axis=1), 1e-30)[:, None]


def inverted_faces(verts, ref_verts, tris):
    """Triangles whose normal turned by more than 90 degrees from the reference body's."""
    return int(((face_normals(verts, tris) * face_normals(ref_verts, tris)).sum(axis=1) < 0).sum())


def _inside(points, poly):
    """Crossing-number test: which of ``points`` (m, 2) lie inside the closed polygon ``poly`` (n, 2)."""
    x, z = points[:, 0:1], points[:, 1:2]
    a, b = poly, np.roll(poly, -1, axis=0)
    cross = (a[:, 1] > z) != (b[:, 1] > z)
    t = (z - a[:, 1]) / np.where(b[:, 1] == a[:, 1], 1e-30, b[:, 1] - a[:, 1])
    xs = a[:, 0] + t * (b[:, 0] - a[:, 0])
    return ((cross & (x < xs)).sum(axis=1) % 2) == 1


def _distance_to(points, poly):
    """Distance (m) from each point to the polygon's boundary."""
    a, b = poly, np.roll(poly, -1, axis=0)
    ab = b - a
    t = np.clip(((points[:, None, :] - a) * ab).sum(-1) / np.maximum((ab ** 2).sum(-1), 1e-30), 0, 1)
    d = points[:, None, :] - (a + t[..., None] * ab)
    return np.sqrt((d ** 2).sum(-1)).min(axis=1)


def _area(p):
    return 0.5 * abs(np.dot(p[:, 0], np.roll(p[:, 1], -1)) - np.dot(p[:, 1], np.roll(p[:, 0], -1)))


def section_overlap(verts, tris, ys, min_area=0.003):
    """Deepest point (m) of one section loop inside another over the planes ``ys``, and its height.

    A body's horizontal section is a set of disjoint loops (torso, arms, thighs); where one part went
    into another, a loop's points lie inside a neighbour. Loops under ``min_area`` (m^2; 30 cm^2) are
    left out: hm08's groin has small closed folds inside the torso section on every body, MakeHuman's
    own included. Returns (depth, y).
    """
    mesh = trimesh.Trimesh(verts, tris, process=False)
    worst, at = 0.0, float("nan")
    for y in ys:
        path = mesh.section(plane_origin=[0, y, 0], plane_normal=[0, 1, 0])
        if path is None:
            continue
        loops = [p for p in (np.asarray(d)[:, [0, 2]] for d in path.discrete) if _area(p) >= min_area]
        for i, p in enumerate(loops):
            for j, q in enumerate(loops):
                if i == j:
                    continue
                inside = _inside(p, q)
                if inside.any():
                    depth = float(_distance_to(p[inside], q).max())
                    if depth > worst:
                        worst, at = depth, float(y)
    return worst, at


def winding_numbers(verts, tris, points):
    """Generalised winding number of each point about the closed mesh (Jacobson et al. 2013): 1 inside a
    part, 0 outside, 2 inside two parts that went into each other, ~0.5 on the skin.

    Unlike the sign of the nearest surface's normal (what :class:`MeshCollider` reads, right for cloth near
    the skin), it stays right where a posed body passes through itself: a forearm sunk into a knee does not
    make the knee's joint read as outside. Sum of the triangles' solid angles (Van Oosterom & Strackee 1983).
    """
    out = np.empty(len(points))
    for i, q in enumerate(np.asarray(points, dtype=np.float64)):
        a, b, c = (verts[tris[:, k]] - q for k in range(3))
        la, lb, lc = (np.linalg.norm(x, axis=1) for x in (a, b, c))
        num = np.einsum("ij,ij->i", a, np.cross(b, c))
        den = (la * lb * lc + np.einsum("ij,ij->i", a, b) * lc + np.einsum("ij,ij->i", b, c) * la
               + np.einsum("ij,ij->i", c, a) * lb)
        out[i] = 2.0 * np.arctan2(num, den).sum() / (4.0 * np.pi)
    return out
