"""The only place where lengths change units.

Internally vfit works in SI units (m, kg, s). The CLI takes centimetres and
kilograms; MakeHuman's assets are in decimetres.
"""
import numpy as np

from .errors import InputError

#: metres per unit, for every length unit vfit accepts.
LENGTH_UNITS = {"m": 1.0, "dm": 0.1, "cm": 0.01, "mm": 0.001}


def guess_length_unit(height, expected_m=1.7):
    """Guess the unit of a mesh from its height (bbox extent in file units).

    Returns the unit whose conversion brings ``height`` closest (in log scale)
    to ``expected_m`` metres, e.g. a 16.6 high body is in decimetres.
    """
    if not np.isfinite(height) or height <= 0:
        raise InputError("cannot guess the units of a mesh with no height (give --units)")
    best = min(LENGTH_UNITS, key=lambda u: abs(np.log(height * LENGTH_UNITS[u] / expected_m)))
    return best
