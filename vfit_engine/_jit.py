"""The one place that holds vfit's Numba options.

Kernels import ``njit`` from here so every kernel compiles with the same
settings and caches to disk. Importing this module imports numba (~0.45 s), so
only kernel modules may import it, and only library code that really runs a
kernel imports those modules: ``vfit --help`` must never reach this file.

fastmath stays off: girths are compared to 0.1 mm and cloth runs are checked
for determinism, and fastmath's reassociation changes results between builds.
"""
import numba

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
