"""The one place that holds vfit's Numba options.

Kernels import ``njit`` from here so every kernel compiles with the same
settings and caches to disk. Importing this module imports numba (~0.45 s), so
only kernel modules may import it, and the CLI imports the engine inside its
commands: ``vfit --help`` must never reach this file.

fastmath stays off: girths are compared to 0.1 mm and cloth runs are checked
for determinism, and fastmath's reassociation changes results between builds.

The cloth kernel opens a few hundred short parallel regions per frame (two threads,
:mod:`vfit_engine.kernels.cloth`). OpenMP's default wait policy spins at every barrier
until the other thread arrives: on a machine where other programs hold the cores,
that thread is often descheduled and each barrier costs a time slice -- a drape
measured 7x slower (95 s against 14 s) beside two other busy programs on two cores,
burning 48 s of CPU spinning. ``OMP_WAIT_POLICY=PASSIVE`` (waiting threads sleep)
is set unless the user set a policy; it must be set before Numba loads its OpenMP
layer, which happens at the first parallel kernel, after this import.
"""
import os
import sys

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
# OpenMP before TBB (Numba's own order is TBB first): with TBB present (a system libtbb, e.g. one that Blender's
# package brings) a process that ran a parallel kernel from a worker thread -- the drape's set-up builds the body's
# collider in a thread pool -- can hang for ever at exit in TBB's finalize (numba/numba#10556; seen here: `vfit
# animate` wrote its report and then spun at 50 % CPU for 48 minutes in unload_tbb). The wait policy above is
# OpenMP's too.
os.environ.setdefault("NUMBA_THREADING_LAYER_PRIORITY", "omp workqueue tbb")


import numba  # noqa: E402  (after the wait policy)

#: Options shared by every kernel. ``cache=True`` keeps warm starts at a few ms.
JIT_OPTIONS = dict(cache=True, nogil=True, fastmath=False, error_model="numpy")


def njit(*args, **kwargs):
    """``numba.njit`` with vfit's preset; extra keyword arguments win
    (``parallel=True`` only where a benchmark shows it pays)."""
    options = dict(JIT_OPTIONS)
    options.update(kwargs)
    if args and callable(args[0]):
        return numba.njit(**options)(args[0])
    return numba.njit(*args, **options)


prange = numba.prange
