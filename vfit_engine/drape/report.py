"""The drape report (``report.json``) and its one-line summaries: what was draped, how long it took, how it fits."""
from __future__ import annotations

import math

#: The quality bars of a drape of a garment that fits its body (the drape issue's acceptance):
#: nothing of the cloth surface deeper than 2 mm inside the body and at most 0.5 % of it inside,
#: yarn strain p99 <= 5 % and every edge <= 10 % (near an opening the body forces wider: what it
#: needs + 5 points), shear p99 <= 15 degrees, settled.
BARS = dict(surface_deeper_than_2mm=0, surface_inside_percent=0.5, p99_strain=0.05, max_strain=0.10,
            shear_p99_deg=15.0)


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


def meets_bars(result, openings=()):
    """True when a DrapeResult meets :data:`BARS` (the strain bar relaxed to ``need + 0.05`` when an
    opening must stretch: those edges are not told apart here, the max is compared with the largest
    allowance)."""
    m = result.metrics
    if not (result.converged and m.get("finite")):
        return False
    need = max([o["required_strain"] for o in openings] + [0.0])
    return bool(m["surface_deeper_than_2mm"] <= BARS["surface_deeper_than_2mm"]
                and m["surface_inside_percent"] <= BARS["surface_inside_percent"]
                and m["p99_strain"] <= BARS["p99_strain"]
                and m["max_strain"] <= max(BARS["max_strain"], need + 0.05)
                and m["shear_p99_deg"] <= BARS["shear_p99_deg"])


def openings_table(openings):
    """The openings as JSON rows (no vertex lists); ``tight``: those the body forces wider."""
    return [{k: v for k, v in o.items() if k != "indices"} for o in openings or ()]


def drape_report(setup=None, result=None, diverged=None, interrupted=None, **context):
    """A JSON-ready dict for ``report.json``.

    Parameters
    ----------
    setup : DrapeSetup or None
    result : DrapeResult or None
        None when the drape diverged (then ``diverged`` is the DrapeDiverged).
    diverged : DrapeDiverged or None
    interrupted : dict or None
        ``signal`` and ``frames`` of a run stopped by Ctrl-C or SIGTERM (then ``result`` is None).
    **context
        Extra keys written as given (garment, body, material, outputs ...).

    Returns
    -------
    dict
        Meshes are in metres; depths in mm; strains are fractions (0.05 = 5 %) of the yarn edges of the
        garment **as given**; angles in degrees (key names and ``units`` say so).
    """
    out = {"command": "drape", "units": {"mesh": "m", "up": "Y", "depth": "mm", "strain": "fraction",
                                         "angle": "deg", "time": "s"}}
    out.update(context)
    if setup is not None:
        openings = openings_table(setup.openings)
        out.update(placement=setup.info["placement"], transfer=setup.info["transfer"], rest=setup.info["rest"],
                   garment_made_on=setup.info["made_on"], pins=setup.pins.info, openings=openings,
                   tight_openings=[o for o in openings if o["required_strain"] > 0],
                   material=setup.material.to_dict(), collider=setup.collider_kind,
                   ground_y_m=setup.info.get("ground_y_m"))
    if diverged is not None:
        out.update(diverged=True, converged=False, message=str(diverged), frames=diverged.frame,
                   last_good_frame=diverged.last_good_frame)
        return _clean(out)
    if interrupted is not None:
        out.update(interrupted=True, diverged=False, converged=False, signal=interrupted["signal"],
                   frames=interrupted["frames"])
        return _clean(out)
    m = dict(result.metrics)
    out.update(
        diverged=False,
        converged=bool(result.converged),
        frames=result.frames,
        steps=result.steps,
        simulated_time_s=result.sim_time,
        wall_time_s=result.wall_time,
        setup_time_s=result.setup_time + (setup.info["setup_time_s"] if setup is not None else 0.0),
        settle=result.settle,
        strain_reference="the flat pattern (its panels as cut), polygon edges" if setup.info["rest"] == "pattern"
        else "the garment as given (its own size), polygon edges",
        **m,
        solver=result.info,
    )
    return _clean(out)
