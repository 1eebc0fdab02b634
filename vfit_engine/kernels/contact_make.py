"""Numba kernel helpers: contact generation (step 3 of :mod:`vfit_engine.kernels.cloth`).

Every contact point that may be within its clearance plus ``reach`` of the body gets the body's closest point
and outward normal, and the half-space it must stay in (the module docstring of :mod:`.cloth`); points proven
clear by an earlier query are skipped, and points resting on the skin reuse their last plane. The argument
arrays are those of :data:`vfit_engine.kernels.cloth.ContactPoints` and ``ContactState``.
"""
import math

from vfit_engine._jit import njit
from vfit_engine.kernels.collide_mesh import query_point

#: A new contact plane turned further than this (cosine, ~8 degrees) from an earlier one, towards the
#: point, marks a crease (:func:`_keep_crease`).
CREASE_COS = 0.99
#: A query measures the body out to the point's band plus this many ``reach`` (beyond it a point is only known to
#: be that far): a point found clear keeps the distance as the bound that spares its next queries while it and
#: the body move, so a wider band spares more. It changes no contact, only how often a clear point is asked
#: again: the still drapes are bit-identical, and a walking suit's cloth took 25 % less time (the walk of
#: ``male_casualsuit02``, 20 frames: 817-823 -> 598-635 ms a frame at 10 against 4; 20 was no better, and slower
#: on the sitting skirt): a point hovering a few millimetres off a moving limb was asked again every substep or
#: two, each query a search that found nothing within the band.
QUERY_REACHES = 10.0
#: Extra depth (m) a query searches beyond the deepest the point's bound allows (rounding).
FLOOR_SLACK = 0.001


@njit(inline="always")
def contact_point(x, v, b, p):
    """Position of contact point ``p``: sum_k b_k x_{v_k}."""
    i0, i1, i2 = v[p, 0], v[p, 1], v[p, 2]
    b0, b1, b2 = b[p, 0], b[p, 1], b[p, 2]
    return (b0 * x[i0, 0] + b1 * x[i1, 0] + b2 * x[i2, 0],
            b0 * x[i0, 1] + b1 * x[i1, 1] + b2 * x[i2, 1],
            b0 * x[i0, 2] + b1 * x[i1, 2] + b2 * x[i2, 2])


@njit
def _sphere_query(px, py, pz, spheres):
    """Signed distance to the nearest sphere's surface, its closest point, outward normal and index."""
    best = math.inf
    qx = qy = qz = nx = ny = nz = 0.0
    best_s = -1
    for s in range(spheres.shape[0]):
        dx, dy, dz = px - spheres[s, 0], py - spheres[s, 1], pz - spheres[s, 2]
        r = math.sqrt(dx * dx + dy * dy + dz * dz)
        d = r - spheres[s, 3]
        if d < best:
            best = d
            best_s = s
            if r > 0.0:
                nx, ny, nz = dx / r, dy / r, dz / r
            else:
                nx, ny, nz = 0.0, 1.0, 0.0
            qx = spheres[s, 0] + spheres[s, 3] * nx
            qy = spheres[s, 1] + spheres[s, 3] * ny
            qz = spheres[s, 2] + spheres[s, 3] * nz
    return best, qx, qy, qz, nx, ny, nz, best_s


@njit(inline="always")
def _bary_on_triangle(grid, t, qx, qy, qz):
    """Barycentric coordinates of point q on grid triangle ``t``, by its corners ``grid.tris[t]`` (Ericson 2005,
    3.4; clamped into the triangle; a degenerate triangle gives its first corner)."""
    rec = grid.tri_data
    ax, ay, az = rec[t, 6], rec[t, 7], rec[t, 8]
    e0x, e0y, e0z = rec[t, 9] - ax, rec[t, 10] - ay, rec[t, 11] - az
    e1x, e1y, e1z = rec[t, 12] - ax, rec[t, 13] - ay, rec[t, 14] - az
    e2x, e2y, e2z = qx - ax, qy - ay, qz - az
    d00 = e0x * e0x + e0y * e0y + e0z * e0z
    d01 = e0x * e1x + e0y * e1y + e0z * e1z
    d11 = e1x * e1x + e1y * e1y + e1z * e1z
    d20 = e2x * e0x + e2y * e0y + e2z * e0z
    d21 = e2x * e1x + e2y * e1y + e2z * e1z
    den = d00 * d11 - d01 * d01
    bb = bc = 0.0
    if den > 0.0:
        bb = min(max((d11 * d20 - d01 * d21) / den, 0.0), 1.0)
        bc = min(max((d00 * d21 - d01 * d20) / den, 0.0), 1.0 - bb)
    return 1.0 - bb - bc, bb, bc


@njit(inline="always")
def _velocity_on_triangle(grid, body_vel, t, qx, qy, qz):
    """The body's velocity (m/s) at point q of grid triangle ``t``: its corners' velocities ``body_vel`` blended
    by q's barycentric coordinates."""
    ba, bb, bc = _bary_on_triangle(grid, t, qx, qy, qz)
    i0, i1, i2 = grid.tris[t, 0], grid.tris[t, 1], grid.tris[t, 2]
    return (ba * body_vel[i0, 0] + bb * body_vel[i1, 0] + bc * body_vel[i2, 0],
            ba * body_vel[i0, 1] + bb * body_vel[i1, 1] + bc * body_vel[i2, 1],
            ba * body_vel[i0, 2] + bb * body_vel[i1, 2] + bc * body_vel[i2, 2])


@njit(inline="always")
def _sag_on_triangle(grid, body_sag, t, qx, qy, qz):
    """The body's extra thickness (m) at point q of grid triangle ``t``: its corners' ``body_sag`` blended."""
    ba, bb, bc = _bary_on_triangle(grid, t, qx, qy, qz)
    return ba * body_sag[grid.tris[t, 0]] + bb * body_sag[grid.tris[t, 1]] + bc * body_sag[grid.tris[t, 2]]


@njit
def make_contacts(x, inv_mass, v, b, skin, spheres, grid, use_grid, reach, max_push, reuse,
                  p_last, d_last, c_n, c_nq, c_h, c_list, c_n2, c_nq2, c_h2, p0, p1, body_vel, sphere_vel, c_u,
                  body_sag, sag_max, ground):
    """Contact half-spaces of the points ``p0 .. p1 - 1`` that may touch the body (step 3), listed in
    ``c_list`` from index ``p0``; returns (contacts, queries). Given the body's velocities (``body_vel``,
    ``sphere_vel``: not empty), a point queried afresh keeps the body's velocity at its closest point in ``c_u``.

    ``ground`` (m; ``-inf``: none) is the height of a still ground plane (normal +y) under the body: one more
    collider, the nearest of which gives a point its plane, as the spheres' and the body's nearest does. A plane
    holds a triangle out wherever it holds its corners, so it needs no more than the points already there.

    Given ``body_sag`` (not empty) the body counts as that much thicker (blended at the closest point): the
    half-space moves out by it. A point found clear keeps as its bound the true distance less the largest
    thickness at its closest triangle's corners, but never less than the band (such a point is queried again
    as soon as it moves). That bound is not strict: cloth drifting towards a thicker feature may enter its
    extra thickness (at most ``sag_max``) before its next query, which pushes it out. With the strict one
    (less ``sag_max``), cloth hovering a few millimetres off the body was queried every substep: 10x the
    queries, a fifth more time per frame.

    In a crease (under the bust, the armpit) a point lies near two surfaces and its closest point
    jumps from one to the other as it moves: a point whose new plane turned by more than
    ``CREASE_COS`` from an earlier one, while still within reach of it, keeps that one as a second
    half-space (``c_n2``, ``c_nq2``; ``c_nq2`` NaN when none; :func:`_keep_crease`) and must satisfy
    both, instead of being pushed to and fro between them."""
    queries = 0
    n_c = 0
    for p in range(p0, p1):
        free = 0.0
        for k in range(3):
            if inv_mass[v[p, k]] > 0.0:
                free += b[p, k]
        if free < 0.5:
            continue  # (mostly) pinned: moving the few free vertices would lever them far
        px, py, pz = contact_point(x, v, b, p)
        mx, my, mz = px - p_last[p, 0], py - p_last[p, 1], pz - p_last[p, 2]
        moved = math.sqrt(mx * mx + my * my + mz * mz)
        band = skin[p] + reach
        if d_last[p] - moved >= band:
            continue
        if moved < reuse and -math.inf < d_last[p] < band:
            # the last query's plane still holds (module docstring)
            d = c_n[p, 0] * px + c_n[p, 1] * py + c_n[p, 2] * pz - c_nq[p]
            c_h[p] = c_nq[p] + min(skin[p], d + max_push)
            if c_nq2[p] == c_nq2[p]:
                d2 = c_n2[p, 0] * px + c_n2[p, 1] * py + c_n2[p, 2] * pz - c_nq2[p]
                c_h2[p] = c_nq2[p] + min(skin[p], d2 + max_push)
            c_list[p0 + n_c] = p
            n_c += 1
            continue
        was_contact = -math.inf < d_last[p] < band
        query_out = band + QUERY_REACHES * reach
        d = bound = query_out
        qx = qy = qz = nx = ny = nz = 0.0
        ux = uy = uz = 0.0
        if use_grid:
            # d_last - moved is a lower bound of the point's distance now (the skip test's): given one, the search
            # need not look deeper into the body than that (with the bumps' thickness and a millimetre to spare)
            low = d_last[p] - moved
            floored = low > -math.inf
            max_in = max(-low, 0.0) + sag_max + FLOOR_SLACK if floored else math.inf
            dg, gqx, gqy, gqz, gnx, gny, gnz, t = query_point(px, py, pz, grid, True, query_out + sag_max,
                                                                max_in, floored)
            if t >= 0:
                e = em = 0.0
                if body_sag.shape[0] > 0:
                    e = _sag_on_triangle(grid, body_sag, t, gqx, gqy, gqz)
                    em = max(body_sag[grid.tris[t, 0]], body_sag[grid.tris[t, 1]], body_sag[grid.tris[t, 2]])
                bound = dg - em
                d, qx, qy, qz, nx, ny, nz = dg - e, gqx + e * gnx, gqy + e * gny, gqz + e * gnz, gnx, gny, gnz
                if body_vel.shape[0] > 0:
                    ux, uy, uz = _velocity_on_triangle(grid, body_vel, t, gqx, gqy, gqz)
        if spheres.shape[0] > 0:
            ds, sqx, sqy, sqz, snx, sny, snz, s = _sphere_query(px, py, pz, spheres)
            bound = min(bound, ds)
            if ds < d:
                d, qx, qy, qz, nx, ny, nz = ds, sqx, sqy, sqz, snx, sny, snz
                if sphere_vel.shape[0] > 0:
                    ux, uy, uz = sphere_vel[s, 0], sphere_vel[s, 1], sphere_vel[s, 2]
        if ground > -math.inf:
            dh = py - ground
            bound = min(bound, dh)
            if dh < d:
                d, qx, qy, qz, nx, ny, nz = dh, px, ground, pz, 0.0, 1.0, 0.0
                ux = uy = uz = 0.0
        if c_u.shape[0] > 0:
            c_u[p, 0], c_u[p, 1], c_u[p, 2] = ux, uy, uz
        queries += 1
        p_last[p, 0], p_last[p, 1], p_last[p, 2] = px, py, pz
        if not d < band:
            # without sag (sag_max 0) this is min(d, query_out) as ever: d >= band there
            d_last[p] = max(band, min(bound, query_out))
            continue
        d_last[p] = d
        _keep_crease(p, px, py, pz, qx, qy, qz, nx, ny, nz, was_contact, band, skin[p], max_push, c_n, c_nq, c_n2, c_nq2, c_h2)
        c_n[p, 0], c_n[p, 1], c_n[p, 2] = nx, ny, nz
        c_nq[p] = nx * qx + ny * qy + nz * qz
        c_h[p] = c_nq[p] + min(skin[p], d + max_push)
        c_list[p0 + n_c] = p
        n_c += 1
    return n_c, queries


@njit(inline="always")
def _keep_crease(p, px, py, pz, qx, qy, qz, nx, ny, nz, was_contact, band, skin, max_push, c_n, c_nq, c_n2, c_nq2, c_h2):
    """The second half-space of point ``p`` whose new plane through ``q`` is ``n`` (before ``c_n`` is
    overwritten): of its previous planes (the first, and the second if any), the nearest one within
    ``band`` that is turned from ``n`` by more than ``CREASE_COS`` and has ``q`` on its outer side;
    else none (``c_nq2`` NaN).

    ``q`` above an earlier tangent plane means the surface turned up towards the point: a crease,
    where the earlier plane lies inside the body and both must hold. On a ridge ``q`` lies below it
    and the earlier plane, outside the body, would hold the cloth off the skin: it is dropped. The
    second plane is kept while it holds, not only on the query that turned, so a point in a crease
    never alternates between one plane and two."""
    best = band
    bx = by = bz = bq = 0.0
    if was_contact:
        for k in range(2):
            if k == 0:
                mx, my, mz, mq = c_n[p, 0], c_n[p, 1], c_n[p, 2], c_nq[p]
            else:
                mx, my, mz, mq = c_n2[p, 0], c_n2[p, 1], c_n2[p, 2], c_nq2[p]
                if mq != mq:
                    continue
            if nx * mx + ny * my + nz * mz >= CREASE_COS or mx * qx + my * qy + mz * qz - mq <= 0.0:
                continue  # the same plane, or a ridge (the new closest point below the old plane)
            dm = mx * px + my * py + mz * pz - mq
            if dm < best:
                best, bx, by, bz, bq = dm, mx, my, mz, mq
    if best < band:
        c_n2[p, 0], c_n2[p, 1], c_n2[p, 2] = bx, by, bz
        c_nq2[p] = bq
        c_h2[p] = bq + min(skin, best + max_push)
    else:
        c_nq2[p] = math.nan
