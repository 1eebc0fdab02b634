"""The body colliders of a drape: the exact mesh with a ramped push, or shapes fitted to the body.

:class:`RampedMesh` hands the exact body mesh to the solver's fused contact kernel with a
per-substep push limit the frame loop ramps; :func:`fit_collider` fits spheres, spheres along the
bones, ellipsoids or convex hulls to the body, and :class:`LimitedPush` wraps them with the same
ramped push limit (and times them).
"""
from __future__ import annotations

import math
import time

import numpy as np

from vfit_engine.errors import InputError


class RampedMesh:
    """The body MeshCollider with a per-substep push limit the frame loop ramps.

    ``contact_args`` makes :class:`~vfit_engine.sim.solver_verlet.SolverVerlet` solve the
    contacts inside its strain-limit iterations (:mod:`vfit_engine.kernels.drape_step`);
    :meth:`project` is the stand-alone projection for other callers.
    """

    def __init__(self, mesh, max_push, reach=0.002, damping=0.0, reuse=0.0):
        self.mesh = mesh
        self.reuse = float(reuse)
        self.damping = float(damping)
        self.max_push = float(max_push)
        self.reach = float(reach)
        self.seconds = 0.0

    def contact_args(self):
        m = self.mesh
        return m.grid, m.skin, self.reach, m.friction, self.max_push, self.damping

    def project(self, x, x_prev, inv_mass):
        t0 = time.perf_counter()
        self.mesh.project(x, x_prev, inv_mass, max_push=self.max_push)
        self.seconds += time.perf_counter() - t0


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


def fit_collider(kind, body_verts, body_tris, body_collider, segments, st, bones=None):
    """The approximate collider ``kind`` fitted to this body (nothing placed by hand)."""
    if kind == "bone-spheres":
        from vfit_engine.collide.bone_spheres import fit_bone_spheres
        from vfit_engine.collide.spheres import SphereCollider

        if bones is None:
            raise InputError("the bone-spheres collider needs the body's skeleton")
        centres, radii, _ = fit_bone_spheres(body_verts, body_tris, bones, per_bone=st.spheres_per_bone)
        return SphereCollider(centres, radii, skin=st.sphere_skin, friction=min(st.friction * 2, 1.0))
    if kind == "spheres":
        from vfit_engine.collide.auto_spheres import fit_spheres
        from vfit_engine.collide.spheres import SphereCollider

        centres, radii = fit_spheres(body_verts, body_tris, body_collider)
        return SphereCollider(centres, radii, skin=st.sphere_skin, friction=min(st.friction * 2, 1.0))
    if segments is None:
        raise InputError(f"the {kind} collider needs the body's segmentation")
    labels, names = segments
    labels = np.asarray(labels, dtype=np.int64)[:body_verts.shape[0]]
    if kind == "ellipsoids":
        from vfit_engine.collide.ellipsoids import fit_ellipsoids

        return fit_ellipsoids(body_verts[:labels.size], labels, names, skin=st.sphere_skin / 2, friction=st.friction)
    from vfit_engine.collide.hulls import fit_hulls

    return fit_hulls(body_verts[:labels.size], labels, names, body_tris=body_tris, skin=st.skin, friction=st.friction)
