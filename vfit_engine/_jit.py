"""The one place that holds vfit's Numba options.

Kernels import ``njit`` from here so every kernel compiles with the same
settings and caches to disk. Importing this module imports numba (~0.45 s), so
only kernel modules may import it, and only library code that really runs a
kernel imports those modules: ``vfit --help`` must never reach this file.

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


def _load_cython_blas():
    """Load ``scipy.linalg.cython_blas`` by itself, without the rest of ``scipy.linalg``.

    Numba's registries, set up at the first kernel call (a cached one too), run ``import
    scipy.linalg.cython_blas`` to see whether BLAS is there; the import system then runs
    ``scipy/linalg/__init__.py`` first, which imports all of scipy.linalg and, through SciPy's array-API
    layer, numpy.f2py, numpy.ma and numpy.testing: ~0.2 s of a 2 s ``vfit morph``, for a check. The
    extension module alone loads in ~20 ms (with its BLAS library), and the import finds it in
    ``sys.modules``. Numba's compiled BLAS calls read their function pointers from this same module,
    so results do not change; a later ``import scipy.linalg`` runs as usual and uses it too. Anything
    unexpected (another SciPy layout) leaves the import to Numba.
    """
    name = "scipy.linalg.cython_blas"
    if name in sys.modules or "scipy.linalg" in sys.modules:
        return
    try:
        from importlib.machinery import EXTENSION_SUFFIXES, ExtensionFileLoader
        from importlib.util import find_spec, module_from_spec, spec_from_file_location

        scipy_spec = find_spec("scipy")
        if scipy_spec is None or not scipy_spec.submodule_search_locations:
            return
        for folder in scipy_spec.submodule_search_locations:
            for suffix in EXTENSION_SUFFIXES:
                path = os.path.join(folder, "linalg", "cython_blas" + suffix)
                if os.path.isfile(path):
                    spec = spec_from_file_location(name, path, loader=ExtensionFileLoader(name, path))
                    module = module_from_spec(spec)
                    spec.loader.exec_module(module)
                    sys.modules[name] = module
                    return
    except Exception:  # noqa: BLE001  (an optimisation only: Numba imports it the usual way)
        sys.modules.pop(name, None)


_load_cython_blas()

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
