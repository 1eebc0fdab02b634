"""The morph solver's settings: tolerances, residual weights, the build path's ends, the reach search.

Kept apart from ``morph.py`` (which imports them all) so the solver's file holds the solver.
"""

#: relative standard error given to the underbust estimate (the survey has no underbust: an assumption)
UNDERBUST_SD = 0.04
#: a girth or height within this of its target counts as met (m); the promise is 1 mm.
TOLERANCE_M = 0.0002
#: mass within this fraction of its target counts as met (the promise is 1 %).
TOLERANCE_MASS = 0.002
#: residual units: a length residual counts in mm (m per mm), a mass residual in 0.1 % (counts like 1 mm)
MM = 1e-3
MASS_UNIT = 1e-3
# A strict hierarchy by weight (residuals in mm): a 1 mm target miss costs 1, a 1 mm
# hold miss 1e-4, a whole unit of a primary channel 1e-10 and of a secondary one 1e-8,
# so a target gives way to holds by only ~HOLD_WEIGHT**2 of their residual.
SOFT_WEIGHT = 0.01
#: an estimate within this (in its weighted residual: 0.01 per mm, so 5 mm; 0.5 % of mass) is close
#: enough: the survey's standard errors are 1-6 cm
SOFT_TOL = 0.05
#: weight of the one goal a reach search pulls far away: it gives way to every target (by ~1e-5 of its pull)
REACH_WEIGHT = 0.003
#: a solve that ends missing a target by less than this (m) tries again with a residual per watched plane
#: (``morph_planes.py``): a miss of millimetres is the extremum jumping between planes
EACH_PLANE_MISS = 5e-3
#: an inner solve that misses a target by more than this (m) at its own planes ends the outer loop
EARLY_EXIT = 1e-3
#: band planes a girth's inner solve watches: the latest this many seen near the extremum (a body
#: without a waist has a flat profile whose minimum wanders between many shallow valleys)
SEEN_PLANES = 8
#: weight of the estimates during a reach search's pull: 1/30 of the pull's, so they do not hold it back
REACH_SOFT = 1e-4
#: where a reach search pulls that goal: these multiples of its estimate
REACH_PULL = (0.5, 2.0)
#: seconds after a solve starts by which the reach searches of a failure end (the API's default; `vfit morph` gives
#: what is left of 2.6 s since the program started): none begins later, and one still running then is cut short
#: ("range not searched in the time limit"), so that a failure answers within ~3 s. Measured in a fresh
#: `vfit morph --bust 70 --underbust 90` on a quiet machine: Python, NumPy, Numba and the body model 0.6 s; in the
#: solve, Numba's first use (its registries, the kernels' cache) 0.6 s and the missed solve 0.65 s; then each range
#: 0.3 s (both done 2.45 s after the start). Uncut, a range can take 1.4 s (waist 90, hips 95, bust 130, underbust
#: 70: the underbust's): that failure took 3.1-3.4 s
RANGE_SEARCH_UNTIL = 2.0
#: the build path's ends. Below -1 the weight slider goes on linearly beyond MakeHuman's 0 (a lean
#: 195 cm / 75 kg man needs -1.35); above 1 it is not extrapolated: there the heavy corner's faces
#: turn over (hands, armpits: 22 faces at 1.1, 78 at 1.2 on the male) and the measure targets reach
#: the heavy customers instead (175 cm / 130 kg men, 160 cm / 110 kg women)
B_MIN, B_MAX = -1.5, 1.0
#: the held bust points stay this much more anterior than any other vertex of their breast (m): the tape's
#: argmax then picks them too
POINT_MARGIN = 1e-4
REG_PRIMARY = 1e-5  # mm-equivalent per unit of channel weight
REG_SECONDARY = 1e-4
