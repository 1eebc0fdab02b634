"""Drape a garment on a body: the one path the CLI, the scripts, the benchmarks and the tests take.

::

    setup = prepare_drape(garment, body, model)       # place, move, pin, check openings, colliders
    result = run_drape(setup, settings, on_frame)      # untangle, simulate until settled, measure
    report = drape_report(setup, result)               # report.json

:mod:`.setup` (:func:`prepare_drape`), :mod:`.loop` (:func:`run_drape`), :mod:`.settings`,
:mod:`.metrics` (surface penetration, yarn strain and shear against the garment as given),
:mod:`.report` and :mod:`.colliders` (shapes fitted to the body).
"""
from vfit_engine.drape.loop import DrapeDiverged, DrapeResult, run_drape
from vfit_engine.drape.report import drape_report, meets_bars
from vfit_engine.drape.settings import DrapeSettings
from vfit_engine.drape.setup import DrapeSetup, Pins, prepare_drape

__all__ = ["DrapeDiverged", "DrapeResult", "DrapeSettings", "DrapeSetup", "Pins", "drape_report", "meets_bars",
           "prepare_drape", "run_drape"]
