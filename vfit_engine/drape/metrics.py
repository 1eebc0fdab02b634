"""What a drape is judged by, measured the way a user sees it.

* **Skin through the cloth** is looked for over the whole cloth surface, not only at its vertices: each
  triangle of each polygon's fan (what viewers draw) is sampled on a barycentric lattice of order
  ``max(SURFACE_ORDER, ceil(longest edge / SURFACE_SPACING))`` -- corners, points along the edges,
  interior points -- and every sample's signed distance to the exact body gives
  ``surface_inside_percent`` (samples inside), ``surface_max_depth_mm`` and the count deeper than 2 mm.
  A triangle whose corners all lie farther out than its longest edge cannot reach the body and is
  counted as outside without sampling. The vertices alone give ``vertex_*`` (what a vertex-only check
  sees).
* **Strain** is the yarn strain ``l / l0 - 1`` of the polygons' own edges (the yarn directions of a quad
  mesh, not triangulation diagonals) against the garment **as given** (its own size, even when the
  cloth was graded to the body): ``max_strain`` over the edges of rest length >= ``MIN_EDGE`` (shorter
  ones are seams and hem turns whose strain is noise), ``p99_strain`` over all edges.
* **Shear** is the change of the polygons' corner angles against the garment as given
  (``shear_p99_deg``, ``shear_max_deg``).
* **Where it is tight**: each edge belongs to the body part under its midpoint (within ``PART_REACH``;
  the body's skin-weight parts); ``strain_by_body_part`` gives each part's edges, p99 and max strain and
  the share of its edges stretched beyond what the fabric gives (``Material.wearable_stretch``). These are
  the cloth's local peaks (a seam, a pinned point), by rig part; whether a region can be worn is the fit
  table's verdict (:mod:`vfit_engine.fit.verdict`, ``report.json["too_tight"]``), which reads the cloth
  round the region as a whole.
"""
from __future__ import annotations

import numpy as np

from vfit_engine.body.segment import PARTS

#: Smallest lattice order of the surface samples (3: corners, two points per edge, the centroid).
SURFACE_ORDER = 3
#: Largest spacing of the surface samples along a triangle's longest edge, m.
SURFACE_SPACING = 0.005
#: Largest lattice order (a 20 cm triangle is sampled every 1 cm).
SURFACE_MAX_ORDER = 20
#: Edges shorter than this at rest (m) are left out of ``max_strain``.
MIN_EDGE = 0.003
#: An edge whose midpoint lies farther than this (m) from the body belongs to no body part.
PART_REACH = 0.03


def surface_samples(verts, tris, order):
    """Points of each triangle's barycentric lattice of ``order`` (corners included).

    Parameters
    ----------
    verts : (n, 3) float64, m
    tris : (t, 3) int64
    order : int

    Returns
    -------
    (t * (order + 1) * (order + 2) / 2, 3) float64, m
    """
    k = np.array([(i, j, order - i - j) for i in range(order + 1) for j in range(order + 1 - i)], float) / order
    return np.einsum("kb,tbd->tkd", k, verts[tris]).reshape(-1, 3)


def surface_penetration(collider, verts, tris):
    """Samples over every triangle against the body (module docstring).

    Returns
    -------
    dict
        ``surface_samples``, ``surface_inside_percent``, ``surface_max_depth_mm``,
        ``surface_deeper_than_2mm``.
    """
    verts = np.ascontiguousarray(verts, dtype=np.float64)
    corners = verts[tris]
    longest = np.max(np.linalg.norm(corners - np.roll(corners, 1, axis=1), axis=2), axis=1)
    d_vert, _, _, _ = collider.query(verts, max_out=float(longest.max(initial=0.0)) + 1e-9, max_in=np.inf)
    clear = np.all(d_vert[tris] > longest[:, None], axis=1)
    order = np.clip(np.ceil(longest / SURFACE_SPACING), SURFACE_ORDER, SURFACE_MAX_ORDER).astype(np.int64)
    total, inside, deep, depth = 0, 0, 0, 0.0
    for m in np.unique(order):
        per = (m + 1) * (m + 2) // 2
        sel = order == m
        total += int(np.count_nonzero(sel)) * per
        todo = sel & ~clear
        if not todo.any():
            continue
        pts = surface_samples(verts, tris[todo], int(m)).reshape(-1, per, 3)
        # the signed distance is 1-Lipschitz: a sample farther from a corner than that corner is from the body
        # cannot be inside; only the others are queried (the counts are the same)
        dc = d_vert[tris[todo]]  # (k, 3), +inf beyond the exact range (clear)
        reach = np.linalg.norm(pts[:, :, None, :] - corners[todo][:, None, :, :], axis=3)  # (k, per, 3)
        maybe = np.max(dc[:, None, :] - reach, axis=2) <= 0.0
        if not maybe.any():
            continue
        d, _, _, _ = collider.query(np.ascontiguousarray(pts[maybe]), max_out=0.0, max_in=np.inf)
        inside += int(np.count_nonzero(d < 0.0))
        deep += int(np.count_nonzero(d < -0.002))
        depth = max(depth, float(-d.min()))
    return dict(surface_samples=total, surface_inside_percent=100.0 * inside / max(total, 1),
                surface_max_depth_mm=1000.0 * max(depth, 0.0), surface_deeper_than_2mm=deep)


def corner_angles(verts, face_verts, face_offsets):
    """(k,) float64, radians: the angle at every polygon corner (face_verts order)."""
    fo = np.asarray(face_offsets, dtype=np.int64)
    fv = np.asarray(face_verts, dtype=np.int64)
    sizes = np.diff(fo)
    face = np.repeat(np.arange(sizes.size), sizes)
    local = np.arange(fv.size) - fo[face]
    prv = fv[fo[face] + (local - 1) % sizes[face]]
    nxt = fv[fo[face] + (local + 1) % sizes[face]]
    u, w = verts[prv] - verts[fv], verts[nxt] - verts[fv]
    return np.arctan2(np.linalg.norm(np.cross(u, w), axis=1), np.einsum("ij,ij->i", u, w))


def yarn_strain(mesh, pos):
    """Strain of the polygons' own edges at ``pos`` against ``mesh`` (the garment as given).

    Returns
    -------
    dict
        ``max_strain`` (edges of rest length >= MIN_EDGE), ``p99_strain``, ``min_strain`` (fractions),
        and ``edge_strain`` ((E,) per edge of ``mesh.edges()``).
    """
    edges = mesh.edges()
    l0 = np.linalg.norm(mesh.verts[edges[:, 1]] - mesh.verts[edges[:, 0]], axis=1)
    ok = l0 > 0
    strain = np.zeros(edges.shape[0])
    strain[ok] = np.linalg.norm(pos[edges[ok, 1]] - pos[edges[ok, 0]], axis=1) / l0[ok] - 1.0
    long_ = l0 >= MIN_EDGE
    return dict(max_strain=float(strain[long_].max()) if long_.any() else 0.0,
                p99_strain=float(np.percentile(strain[ok], 99)) if ok.any() else 0.0,
                min_strain=float(strain[ok].min()) if ok.any() else 0.0, edge_strain=strain)


def shear(mesh, pos):
    """Change of the polygons' corner angles at ``pos`` against ``mesh``: ``shear_p99_deg``, ``shear_max_deg``."""
    d = np.degrees(np.abs(corner_angles(pos, mesh.face_verts, mesh.face_offsets)
                          - corner_angles(mesh.verts, mesh.face_verts, mesh.face_offsets)))
    if not d.size:
        return dict(shear_p99_deg=0.0, shear_max_deg=0.0)
    return dict(shear_p99_deg=float(np.percentile(d, 99)), shear_max_deg=float(d.max()))


def drape_metrics(setup, pos):
    """All the figures of a drape of ``setup`` ending at ``pos`` (module docstring).

    Returns
    -------
    dict
        ``finite``; surface figures (:func:`surface_penetration`); ``vertex_inside_count``,
        ``vertex_inside_percent``, ``vertex_max_depth_mm``; :func:`yarn_strain` (against the garment as
        given; ``edge_strain`` dropped), :func:`strain_by_part` and, for a graded garment, ``graded_max_strain`` /
        ``graded_p99_strain`` against the graded rest shape; :func:`shear`.
    """
    pos = np.asarray(pos, dtype=np.float64)
    out = dict(finite=bool(np.all(np.isfinite(pos))))
    if not out["finite"]:
        return out
    mesh = setup.garment.mesh
    out.update(surface_penetration(setup.collider, pos, mesh.triangles()))
    pen = setup.collider.penetration(pos)
    n = max(pos.shape[0], 1)
    out.update(vertex_inside_count=pen["inside_count"], vertex_inside_percent=100.0 * pen["inside_count"] / n,
               vertex_max_depth_mm=1000.0 * pen["max_depth_m"])
    strain = yarn_strain(mesh, pos)
    out.update(strain_by_part(setup, pos, strain.pop("edge_strain")))
    out.update(strain)
    if setup.info.get("rest") == "graded":
        graded = yarn_strain(setup.rest_mesh, pos)
        out.update(graded_max_strain=graded["max_strain"], graded_p99_strain=graded["p99_strain"])
    out.update(shear(mesh, pos))
    return out


def strain_by_part(setup, pos, edge_strain):
    """``strain_by_body_part`` (module docstring; empty without ``setup.body_parts``).

    Parameters
    ----------
    setup : DrapeSetup
    pos : (n, 3) float64, m
    edge_strain : (E,) float64
        :func:`yarn_strain`'s per edge of ``setup.garment.mesh.edges()``.
    """
    if setup.body_parts is None:
        return {}
    mesh = setup.garment.mesh
    edges = mesh.edges()
    l0 = np.linalg.norm(mesh.verts[edges[:, 1]] - mesh.verts[edges[:, 0]], axis=1)
    mid = 0.5 * (pos[edges[:, 0]] + pos[edges[:, 1]])
    _, _, _, tri = setup.collider.query(mid, max_out=PART_REACH, max_in=np.inf)
    part = np.full(edges.shape[0], -1, dtype=np.int64)
    near = tri >= 0
    part[near] = setup.body_parts[setup.body_tris[tri[near], 0]]
    limit = float(setup.material.wearable_stretch)
    rows = {}
    for k, name in enumerate(PARTS):
        sel = (part == k) & (l0 > 0)
        if not sel.any():
            continue
        s = edge_strain[sel]
        long_ = l0[sel] >= MIN_EDGE
        top = float(s[long_].max()) if long_.any() else 0.0
        rows[name] = dict(edges=int(sel.sum()), p99_strain=float(np.percentile(s, 99)), max_strain=top,
                          over_fabric_limit_percent=100.0 * float(np.mean(s > limit)))
    return dict(strain_by_body_part=rows)


def vertex_strain(mesh, pos):
    """(n,) float64: the largest yarn strain of the edges at each vertex (against ``mesh``), for fit maps."""
    edges = mesh.edges()
    strain = yarn_strain(mesh, pos)["edge_strain"]
    out = np.full(mesh.n_verts, -np.inf)
    np.maximum.at(out, edges[:, 0], strain)
    np.maximum.at(out, edges[:, 1], strain)
    out[~np.isfinite(out)] = 0.0
    return out
