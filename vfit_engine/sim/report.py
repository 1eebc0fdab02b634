"""The drape report (``report.json``): what was simulated, how long it took and how good it is."""
from __future__ import annotations

import math


def _clean(value):
    """JSON-safe copy: tuples to lists, non-finite floats to None, numpy scalars to Python."""
    if isinstance(value, dict):
        return {str(k): _clean(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_clean(v) for v in value]
    if hasattr(value, "item") and not isinstance(value, (str, bytes)):
        value = value.item()
    if isinstance(value, float):
        return round(value, 9) if math.isfinite(value) else None
    return value


#: The quality bars of a drape on a body (the cloth issue's acceptance): nothing deeper than 2 mm
#: inside the body, at most 0.5 % of the vertices inside at all, structural strain p99 <= 5 % and
#: max <= 10 %, settled, finite.
BARS = dict(deep_count=0, inside_fraction=0.005, p99_strain=0.05, max_strain=0.10)


def meets_bars(result):
    """True when a DrapeResult meets :data:`BARS`."""
    m = result.metrics
    return bool(result.converged and m["finite"] and m["deep_count"] <= BARS["deep_count"]
                and m["inside_fraction"] <= BARS["inside_fraction"] and m["p99_strain"] <= BARS["p99_strain"]
                and m["max_strain"] <= BARS["max_strain"])


def drape_report(result=None, diverged=None, **context):
    """A JSON-ready dict for ``report.json``.

    Parameters
    ----------
    result : DrapeResult or None
        None when the drape diverged (then ``diverged`` is the DrapeDiverged).
    diverged : DrapeDiverged or None
    **context
        Extra keys written as given (garment, body, material, outputs ...).

    Returns
    -------
    dict
        Lengths in the mesh outputs are metres; depths in mm; strains as fractions (0.05 = 5 %):
        ``max_strain`` / ``p99_strain`` against the cloth's rest lengths (the transferred garment with
        ``rest="transferred"``), ``garment_max_strain`` / ``garment_p99_strain`` against the garment as given;
        ``tight_openings``: openings smaller than the body part they go round, whose
        ``required_strain`` bounds the strain from below.
    """
    out = {"command": "drape", "units": {"mesh": "m", "up": "Y", "depth": "mm", "strain": "fraction",
                                         "time": "s"}}
    out.update(context)
    if diverged is not None:
        out.update(diverged=True, converged=False, message=str(diverged), frames=diverged.frame,
                   last_good_frame=diverged.last_good_frame)
        return _clean(out)
    m = result.metrics
    openings = [{k: v for k, v in o.items() if k != "indices"} for o in (result.openings or [])]
    out.update(
        diverged=False,
        converged=bool(result.converged),
        frames=result.frames,
        steps=result.steps,
        simulated_time_s=result.sim_time,
        wall_time_s=result.wall_time,
        setup_time_s=result.setup_time,
        collision_time_s=result.collide_time,
        final_max_speed_m_s=result.max_speed,
        max_penetration_mm=m.get("max_depth_mm"),
        inside_count=m.get("inside_count"),
        inside_percent=None if m.get("inside_fraction") is None else 100.0 * m["inside_fraction"],
        deeper_than_2mm_count=m.get("deep_count"),
        max_strain=m.get("max_strain"),
        p99_strain=m.get("p99_strain"),
        strain_edges="structural",
        garment_max_strain=m.get("garment_strain", {}).get("max"),
        garment_p99_strain=m.get("garment_strain", {}).get("p99"),
        softened_spring_fraction=result.softened_fraction,
        openings=openings,
        tight_openings=[o for o in openings if o["required_strain"] > 0],
        settings=result.settings,
    )
    return _clean(out)
