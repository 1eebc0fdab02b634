"""What a drape is judged by: penetration into the exact body and edge strain."""
from __future__ import annotations

import numpy as np


def drape_metrics(model, pos, body_collider):
    """Penetration and strain of draped cloth.

    Parameters
    ----------
    model : Model
    pos : (n, 3) float64, m
    body_collider : MeshCollider
        The exact body (inside = negative signed distance).

    Returns
    -------
    dict
        ``max_depth_mm``, ``inside_count``, ``inside_fraction``, ``deep_count`` (deeper than 2 mm),
        ``max_strain``, ``p99_strain`` (structural springs, ``l / l0 - 1``), ``finite``.
    """
    from vfit_engine.garment.springs import STRUCTURAL

    pos = np.asarray(pos, dtype=np.float64)
    finite = bool(np.all(np.isfinite(pos)))
    out = dict(finite=finite)
    if not finite:
        return out
    pen = body_collider.penetration(pos)
    strain = model.spring_strain(pos)[model.spring_type == STRUCTURAL]
    n = max(pos.shape[0], 1)
    out.update(
        max_depth_mm=1000.0 * pen["max_depth_m"],
        inside_count=pen["inside_count"],
        inside_fraction=pen["inside_count"] / n,
        deep_count=int(np.count_nonzero(pen["depth_m"] > 0.002)),
        max_strain=float(strain.max()) if strain.size else 0.0,
        p99_strain=float(np.percentile(strain, 99)) if strain.size else 0.0,
    )
    return out


def edge_strain(mesh, pos):
    """Strain ``l / l0 - 1`` of the mesh's edges at ``pos`` against the mesh's own vertices.

    Parameters
    ----------
    mesh : MeshData
        Its vertices give the rest lengths.
    pos : (n, 3) float64, m

    Returns
    -------
    dict
        ``max`` and ``p99`` (fractions) over the unique edges.
    """
    edges = mesh.edges()
    rest_pos = mesh.verts
    l0 = np.linalg.norm(rest_pos[edges[:, 1]] - rest_pos[edges[:, 0]], axis=1)
    ok = l0 > 0
    strain = np.linalg.norm(pos[edges[ok, 1]] - pos[edges[ok, 0]], axis=1) / l0[ok] - 1.0
    if not strain.size:
        return dict(max=0.0, p99=0.0)
    return dict(max=float(strain.max()), p99=float(np.percentile(strain, 99)))
