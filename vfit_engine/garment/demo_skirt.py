"""vfit's own demo garment: a flared skirt made on MakeHuman's average female body.

It is the garment ``make demo`` drapes (the MakeHuman clothes in ``shared/`` are not shipped with
vfit). Rebuild ``data/garments/skirt.obj`` with::

    python -m vfit_engine.garment.demo_skirt [OUT.obj]

which calls :func:`flared_skirt` with its defaults on ``BodyModel.load().default_verts("female")``
(64 vertices round x 24 rings = 1,536 vertices, 1,472 quads with UVs; metres, Y up). The file is
generated, deterministic, and as free as the rest of vfit's data (CC0).

The skirt, as a pattern maker would give it (the garment's own girths, m):

* **waist** ``WAIST`` = 0.74: the waistband, sized for the demo body's 72 cm waist with 2 cm of
  ease. It is made at the natural waist of the average female body (waist 65.3 cm), that body's
  section grown outward evenly (1.4 cm off its skin); on the demo body the pin fit
  (:mod:`vfit_engine.garment.pin_fit`) lowers it until it is no longer than itself, 2-3 mm off
  the skin. (On the average body itself it stays 1.4 cm off: it is a size larger than that body.)
* **hips** ``HIPS`` = 1.02 at the body's widest hip level (the demo body's hips are 98 cm). From
  the waist to the hips every ring follows the body, its ease going evenly from the waistband's
  to the hips'. At the waist a ring follows the body's own section (a shaped centre-back seam:
  the band lies in the small of the back instead of bridging it by ~6 mm); over the upper half of
  that span (``follow``) it turns into the section's convex hull, the tape line that bridges the
  spine and the cleft between the buttocks as cloth does.
* **hem** ``HEM`` = 2.40 at ``LENGTH`` = 0.55 below the waist (vertically, as made): below the hips
  the skirt flares, its girth growing linearly to the hem, 2.35 times the hips (a little more
  than a half-circle skirt). A plain tube hip-sized does not fold; this much cloth hangs in folds.
  Hanging, the flare falls about 8 cm longer than it was made (63 cm from the waist on the demo
  body, to just below the knee).

UVs: u along the rings (the seam at the centre back), v down the centre back by arc length.

:func:`tube_skirt` (a plain cylinder round the hips) is kept for tests that need a small garment.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from scipy.spatial import ConvexHull

from vfit_engine.body.levels import body_levels
from vfit_engine.body.model import N_BODY, BodyModel, data_dir
from vfit_engine.io.mesh import write_mesh
from vfit_engine.io.meshdata import mesh_from_faces
from vfit_engine.section import MeshSections

#: The demo skirt's girths at the waist, the hips and the hem, and its length, m (module docstring).
WAIST, HIPS, HEM, LENGTH = 0.74, 1.02, 2.40, 0.55
#: Samples of the dense curves a ring is resampled from: per corner arc of a grown hull; round the body.
_ARC_STEPS = 16
_ANGLES = 1440


def flared_skirt(body_verts, body_tris, waist=WAIST, hips=HIPS, hem=HEM, length=LENGTH, follow=0.5,
                 around=64, rows=24):
    """A flared skirt of quads (with UVs) from the body's natural waist down (module docstring).

    Parameters
    ----------
    body_verts : (n >= 13380, 3) float64, m
        The body the skirt is made on (its first 13,380 vertices: the visible hm08 body).
    body_tris : (t, 3) int64
        Body triangles.
    waist, hips, hem : float, m
        Girths of the skirt at its top ring, at the body's widest hip level and at its hem.
    length : float, m
        From the waist ring down to the hem ring (vertical).
    follow : float
        Share of the waist-to-hips span over which a ring turns from the body's own section into
        its convex hull.
    around, rows : int
        Vertices round each ring; rings (the first is the waistband, the last the hem).

    Returns
    -------
    vfit_engine.io.meshdata.MeshData
        ``rows * around`` vertices in rings from the waist down, each ring starting at the centre
        back and running round through the body's left (+x); ``(rows - 1) * around`` quads facing
        outward; UVs.

    Raises
    ------
    ValueError
        The waist or hip girth leaves no ease on this body (at least 2 mm all round).
    """
    v = np.ascontiguousarray(np.asarray(body_verts, dtype=np.float64)[:N_BODY])
    tris = np.asarray(body_tris, dtype=np.int64)
    lv = body_levels(v, tris)
    cx, y_w = lv["center_x"], lv["waist_y"]
    sec = MeshSections(tris, v.shape[0])
    scan = np.arange(y_w, lv["crotch_y"], -0.005)
    y_h = float(scan[int(np.nanargmax(sec.girths(v, scan, x0=cx)))])  # the widest hip level
    y_hem = y_w - length
    if not y_hem < y_h:
        raise ValueError(f"skirt length {length} m ends above the hips ({y_w - y_h:.3f} m below the waist)")

    def ring_at(y, girth_target=None, d=None):
        """Dense ring curve at ``y`` grown by ``d``, or by the ``d`` that gives ``girth_target``."""
        loop, hull = _torso_section(sec, v, max(y, y_h), cx)
        beta = max(0.0, 1.0 - (y_w - y) / (follow * (y_w - y_h))) if y >= y_h and follow > 0 else 0.0

        def curve(dd):
            grown = _grown(hull, dd)
            if beta == 0.0:
                return grown
            c = hull.mean(axis=0)
            phi = np.linspace(-np.pi, np.pi, _ANGLES, endpoint=False)
            r = (1.0 - beta) * _radii(grown, c, phi) + beta * _radii(_shifted(loop, dd), c, phi)
            return c + r[:, None] * np.stack([np.cos(phi), np.sin(phi)], axis=1)

        if d is None:  # the perimeter grows by ~2 pi per metre of d: a few Newton steps with that slope
            d = 0.0
            for _ in range(3):
                d += (girth_target - _perimeter(curve(d))) / (2 * np.pi)
        return curve(d), d

    _, d_w = ring_at(y_w, waist)
    _, d_h = ring_at(y_h, hips)
    if min(d_w, d_h) < 0.002:
        raise ValueError(f"skirt waist {waist} m / hips {hips} m leave no ease on this body")
    ys = np.linspace(y_w, y_hem, rows)
    rings = []
    for y in ys:
        if y >= y_h:
            d = d_w + (d_h - d_w) * (y_w - y) / (y_w - y_h)
        else:
            d = d_h + (hem - hips) / (2 * np.pi) * (y_h - y) / (y_h - y_hem)
        xz = _even(ring_at(y, d=d)[0], around, cx)
        rings.append(np.stack([xz[:, 0], np.full(around, y), xz[:, 1]], axis=1))
    verts = np.concatenate(rings)
    r, i = np.divmod(np.arange((rows - 1) * around), around)
    j = (i + 1) % around
    faces = np.stack([r * around + i, r * around + j, (r + 1) * around + j, (r + 1) * around + i], axis=1)
    w = around + 1  # UV columns: the centre-back seam is split
    face_uvs = np.stack([r * w + i, r * w + i + 1, (r + 1) * w + i + 1, (r + 1) * w + i], axis=1)
    back = verts[::around]
    down = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(back, axis=0), axis=1))])
    uu, vv = np.meshgrid(np.arange(w) / around, 1.0 - down / down[-1])
    uvs = np.stack([uu.ravel(), vv.ravel()], axis=1)
    return mesh_from_faces(verts, faces, uvs=uvs, face_uvs=face_uvs)


def _perimeter(p):
    return float(np.linalg.norm(np.roll(p, -1, axis=0) - p, axis=1).sum())


def _torso_section(sections, verts, y, cx):
    """The torso loop at height ``y`` and its convex hull, both (k, 2) (x, z) m, counter-clockwise."""
    loops = [p for p in sections.loops(verts, y) if len(p) >= 3 and p[:, 0].min() <= cx <= p[:, 0].max()]
    loop = max(loops, key=lambda q: np.ptp(q[:, 0]))
    area2 = np.sum(loop[:, 0] * np.roll(loop[:, 1], -1) - np.roll(loop[:, 0], -1) * loop[:, 1])
    if area2 < 0:
        loop = loop[::-1]
    return loop, loop[ConvexHull(loop).vertices]  # scipy gives 2-D hulls counter-clockwise


def _grown(hull, d):
    """Dense closed curve (k, 2): the convex counter-clockwise ``hull`` grown by ``d`` (Minkowski sum
    with a disc: its perimeter is the hull's + 2 pi d)."""
    e = np.roll(hull, -1, axis=0) - hull
    out = np.stack([e[:, 1], -e[:, 0]], axis=1) / np.linalg.norm(e, axis=1, keepdims=True)
    a1 = np.arctan2(out[:, 1], out[:, 0])  # outward normal of the edge leaving each corner
    a0 = np.roll(a1, 1)  # ... and of the edge arriving
    ang = a0[:, None] + ((a1 - a0) % (2 * np.pi))[:, None] * np.linspace(0.0, 1.0, _ARC_STEPS + 1)
    return (hull[:, None, :] + d * np.stack([np.cos(ang), np.sin(ang)], axis=2)).reshape(-1, 2)


def _shifted(loop, d):
    """The counter-clockwise polygon ``loop`` (k, 2) moved out along its vertex normals by ``d``."""
    t = np.roll(loop, -1, axis=0) - np.roll(loop, 1, axis=0)
    return loop + d * np.stack([t[:, 1], -t[:, 0]], axis=1) / np.linalg.norm(t, axis=1, keepdims=True)


def _radii(curve, c, phi):
    """(len(phi),) distances from ``c`` (2,) to the star-shaped closed ``curve`` (k, 2) along the
    directions ``phi`` (radians, from +x towards +z)."""
    q = curve - c
    a = np.unwrap(np.arctan2(q[:, 1], q[:, 0]))
    r = np.linalg.norm(q, axis=1)
    a, r = np.append(a, a[0] + 2 * np.pi), np.append(r, r[0])
    return np.interp((phi - a[0]) % (2 * np.pi) + a[0], a, r)


def _even(curve, n, cx):
    """``n`` points evenly spaced along the counter-clockwise closed ``curve`` (k, 2) (x, z), the
    first where it crosses ``x = cx`` at the back (smallest z)."""
    nxt = np.roll(curve, -1, axis=0)
    cross = np.flatnonzero((curve[:, 0] - cx) * (nxt[:, 0] - cx) <= 0)
    dx = nxt[cross, 0] - curve[cross, 0]
    s = np.divide(cx - curve[cross, 0], dx, out=np.zeros(cross.size), where=dx != 0)
    z = curve[cross, 1] + s * (nxt[cross, 1] - curve[cross, 1])
    k = int(np.argmin(z))
    start = np.array([cx, z[k]])
    pts = np.concatenate([[start], np.roll(curve, -(cross[k] + 1), axis=0), [start]])
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
    want = np.arange(n) * arc[-1] / n
    return np.stack([np.interp(want, arc, pts[:, 0]), np.interp(want, arc, pts[:, 1])], axis=1)


def tube_skirt(body_verts, body_tris, around=48, rows=10, clearance=0.03, below_crotch=0.10):
    """An open cylinder of quads (with UVs) from the body's waist to below its crotch.

    Parameters
    ----------
    body_verts : (n >= 13380, 3) float64, m
    body_tris : (t, 3) int64 body triangles
    around, rows : int
        Quads around and down.
    clearance : float, m
        Gap between the cylinder and the widest point of the hips, so the skirt also
        starts clear of somewhat larger bodies.
    below_crotch : float, m
        How far the hem hangs below the crotch.

    Returns
    -------
    vfit_engine.io.meshdata.MeshData
    """
    lv = body_levels(body_verts, body_tris)
    top, bottom = lv["waist_y"], lv["crotch_y"] - below_crotch
    cx = lv["center_x"]
    band = body_verts[(body_verts[:, 1] < top) & (body_verts[:, 1] > lv["crotch_y"])
                      & (np.abs(body_verts[:, 0] - cx) < 0.2)]
    cz = 0.5 * (band[:, 2].min() + band[:, 2].max())
    radius = float(np.max(np.hypot(band[:, 0] - cx, band[:, 2] - cz))) + clearance
    ys = np.linspace(top, bottom, rows)
    ang = 2 * np.pi * np.arange(around) / around
    verts = np.array([[cx + radius * np.sin(a), y, cz + radius * np.cos(a)] for y in ys for a in ang])
    faces, face_uvs = [], []
    uvs = np.array([[i / around, 1 - r / (rows - 1)] for r in range(rows) for i in range(around + 1)])
    for r in range(rows - 1):
        for i in range(around):
            j = (i + 1) % around
            faces.append([r * around + i, (r + 1) * around + i, (r + 1) * around + j, r * around + j])
            face_uvs.append([r * (around + 1) + i, (r + 1) * (around + 1) + i,
                             (r + 1) * (around + 1) + i + 1, r * (around + 1) + i + 1])
    return mesh_from_faces(verts, np.array(faces), uvs=uvs, face_uvs=np.array(face_uvs))


def main(argv=None):
    """Write the demo skirt (:func:`flared_skirt` on the average female body) to ``argv[0]`` or
    ``data/garments/skirt.obj``."""
    args = sys.argv[1:] if argv is None else argv
    out = Path(args[0]) if args else data_dir() / "garments" / "skirt.obj"
    out.parent.mkdir(parents=True, exist_ok=True)
    model = BodyModel.load()
    mesh = flared_skirt(model.default_verts("female"), model.body_tris)
    write_mesh(out, mesh, header=[f"vfit demo garment: a flared skirt (waist {100 * WAIST:g}, hips {100 * HIPS:g}, "
                                  f"hem {100 * HEM:g}, length {100 * LENGTH:g} cm) made on the average female body",
                                  "units: metres, Y up; generated by python -m vfit_engine.garment.demo_skirt"])
    print(f"wrote {out} ({mesh.n_verts} vertices, {mesh.n_faces} quads)")


if __name__ == "__main__":
    main()
