"""The body colliders of a drape: the exact body mesh, or shapes fitted to the body.

The exact mesh (:class:`vfit_engine.collide.body_mesh.MeshCollider`) and sphere sets run inside the
solver's kernel (:mod:`vfit_engine.kernels.cloth`); ellipsoids and convex hulls project the cloth after
every substep, wrapped in :class:`LimitedPush` so their pushes ramp like the kernel's.
:func:`fitted_collider` fits the approximate ones to a body, nothing placed by hand.
"""
from __future__ import annotations

import math
import time

import numpy as np

from vfit_engine.body.model import N_BODY
from vfit_engine.body.segment import segment
from vfit_engine.collide.auto_spheres import fit_spheres
from vfit_engine.collide.bone_spheres import fit_bone_spheres, skeleton_bones
from vfit_engine.collide.ellipsoids import fit_ellipsoids
from vfit_engine.collide.hulls import fit_hulls
from vfit_engine.errors import InputError

#: Body colliders of :func:`drape`: the exact body mesh, or shapes fitted to the body.
COLLIDERS = ("mesh", "spheres", "bone-spheres", "ellipsoids", "hulls")


class LimitedPush:
    """A fitted collider whose pushes are limited to ``max_push`` per substep (ramped by the frame
    loop like the mesh collider's) and whose ``project`` time is summed (``seconds``).

    Shapes fitted around the body overlap a garment made for it by centimetres at the start (an
    ellipsoid bounds its part, so it stands off the skin); pushing all of that out in one substep
    would stretch the springs around it and launch the cloth. The velocity the collider leaves
    (its friction and restitution) is kept; only the position change is shortened.
    """

    def __init__(self, inner, max_push=math.inf):
        self.inner = inner
        self.max_push = float(max_push)
        self.seconds = 0.0
        self._before = None

    def project(self, x, x_prev, inv_mass):
        t0 = time.perf_counter()
        if self._before is None or self._before.shape != x.shape:
            self._before, self._len = np.empty_like(x), np.empty(x.shape[0])
        before, length = self._before, self._len
        np.copyto(before, x)
        self.inner.project(x, x_prev, inv_mass)
        # x_prev -= x, then x = before + scaled push, then x_prev += x: the velocity is unchanged
        np.subtract(x_prev, x, out=x_prev)
        np.subtract(x, before, out=x)
        np.sqrt(np.einsum("ij,ij->i", x, x, out=length), out=length)
        np.maximum(length, self.max_push, out=length)
        np.divide(self.max_push, length, out=length)
        x *= length[:, None]
        x += before
        np.add(x_prev, x, out=x_prev)
        self.seconds += time.perf_counter() - t0


def fitted_collider(kind, model, body, mesh_collider, settings):
    """The approximate collider ``kind`` fitted to ``body`` (nothing placed by hand).

    Parameters
    ----------
    kind : {"spheres", "bone-spheres", "ellipsoids", "hulls"}
    model : BodyModel
    body : Body
    mesh_collider : MeshCollider
        The exact body (the sphere cover is fitted inside it).
    settings : DrapeSettings

    Returns
    -------
    spheres : (S, 4) float64 or None
        Centre and radius (m, the relative ``sphere_skin`` included) of a sphere set.
    project : LimitedPush or None
        An ellipsoid or hull collider.
    """
    body_verts, body_tris = body.surface, model.body_tris
    if kind in ("spheres", "bone-spheres"):
        if kind == "spheres":
            centres, radii = fit_spheres(body_verts, body_tris, mesh_collider)
        else:
            if not body.has_helpers:
                raise InputError("the bone-spheres collider needs the body's helper vertices (its skeleton): "
                                 "build the body from measurements instead of reading it from a file")
            centres, radii, _ = fit_bone_spheres(body_verts, body_tris, skeleton_bones(model, body.verts),
                                                 per_bone=settings.spheres_per_bone)
        radii = np.asarray(radii, dtype=np.float64) * (1.0 + settings.sphere_skin)
        return np.ascontiguousarray(np.column_stack([centres, radii])), None
    if kind not in ("ellipsoids", "hulls"):
        raise InputError(f"unknown collider {kind!r}; use one of {', '.join(COLLIDERS)}")

    seg = segment(model, body.verts)
    labels = np.asarray(seg.labels, dtype=np.int64)[:N_BODY]
    c = settings.contact
    if kind == "ellipsoids":
        inner = fit_ellipsoids(body_verts, labels, seg.names, skin=settings.sphere_skin / 2, friction=c.friction)
    else:
        inner = fit_hulls(body_verts, labels, seg.names, body_tris=body_tris, skin=c.skin, friction=c.friction)
    return None, LimitedPush(inner, settings.push_start)
