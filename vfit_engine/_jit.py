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

A cached kernel is never stale. Numba stamps a kernel's cache with its own file only, but a kernel inlines
the helpers it calls from other modules (:mod:`.kernels.cloth` those of :mod:`.kernels.bending`,
:mod:`.kernels.springs`, ...): edited there, the cached kernel would run the old helper. So every function
compiled through :func:`njit` gets :class:`StampedLocator`: Numba's own locator (the cache stays where Numba
puts it: the kernels' ``__pycache__``, or ``NUMBA_CACHE_DIR``, or the user-wide cache when the package is
read-only) with the stamp of :func:`source_stamp`, a hash of the kernel's module, of every module of its
folder it imports, directly or through another, and of :data:`JIT_OPTIONS`. Any edit to one of them makes the stored index stale: Numba
compiles afresh and overwrites it in place, so nothing piles up and no cache ever needs deleting. A kernel
module therefore takes helpers and constants only from its own folder (``tests/test_numba_cache.py``).
"""
import functools
import hashlib
import os
import re
import sys
from pathlib import Path

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
# OpenMP before TBB (Numba's own order is TBB first): with TBB present (a system libtbb, e.g. one that Blender's
# package brings) a process that ran a parallel kernel from a worker thread -- the drape's set-up builds the body's
# collider in a thread pool -- can hang for ever at exit in TBB's finalize (numba/numba#10556; seen here: `vfit
# animate` wrote its report and then spun at 50 % CPU for 48 minutes in unload_tbb). The wait policy above is
# OpenMP's too.
os.environ.setdefault("NUMBA_THREADING_LAYER_PRIORITY", "omp workqueue tbb")


import numba  # noqa: E402  (after the wait policy)
from numba.core import caching  # noqa: E402

#: Options shared by every kernel. ``cache=True`` keeps warm starts at a few ms.
JIT_OPTIONS = dict(cache=True, nogil=True, fastmath=False, error_model="numpy")


#: An import statement (a parenthesised list of names included): the words in it that name a module of the
#: kernel's folder are the modules it reads (a word too many only widens the stamp).
IMPORT = re.compile(r"^[ \t]*(?:from|import)[ \t][^\n(]*(?:\([^)]*\))?[^\n]*", re.M)

#: Code objects of the functions compiled through :func:`njit` (the ones :class:`StampedLocator` stamps).
_STAMPED = set()


def njit(*args, **kwargs):
    """``numba.njit`` with vfit's preset; extra keyword arguments win
    (``parallel=True`` only where a benchmark shows it pays)."""
    options = dict(JIT_OPTIONS)
    options.update(kwargs)
    if args and callable(args[0]):
        return _jit(args[0], (), options)
    return lambda func: _jit(func, args, options)


def _jit(func, signatures, options):
    # registered before numba.njit, which makes the function's cache (and asks the locators) at once
    _STAMPED.add(func.__code__)
    return numba.njit(*signatures, **options)(func)


@functools.lru_cache(maxsize=None)
def source_stamp(py_file):
    """Hash of a kernel module, every module of its folder it imports (directly or through another one) and
    :data:`JIT_OPTIONS`: what a cached kernel of ``py_file`` was compiled from.

    Parameters
    ----------
    py_file : str
        The kernel's module file.

    Returns
    -------
    str
        SHA-256 hex digest (each file read once per process: about a millisecond for the cloth kernel's six).
    """
    path = Path(py_file).resolve()
    texts, todo = {}, [path]
    while todo:
        module = todo.pop()
        if module not in texts:
            texts[module], imported = _module_source(module)
            todo.extend(imported)
    digest = hashlib.sha256(repr(sorted(JIT_OPTIONS.items())).encode())
    for module in sorted(texts):
        digest.update(f"\0{module.name}\0".encode() + texts[module])
    return digest.hexdigest()


@functools.lru_cache(maxsize=None)
def _module_source(path):
    """A module's bytes and the files of its folder that it imports."""
    text = path.read_bytes()
    words = set(re.findall(r"\w+", " ".join(IMPORT.findall(text.decode("utf-8", "replace")))))
    return text, [path.parent / f"{w}.py" for w in sorted(words.intersection(_modules(path.parent)))]


@functools.lru_cache(maxsize=None)
def _modules(folder):
    """The names of a folder's modules."""
    return frozenset(name[:-3] for name in os.listdir(folder) if name.endswith(".py"))


class StampedLocator:
    """Where and how fresh a kernel of :func:`njit` is cached: Numba's own locator for it (``inner``) with
    :func:`source_stamp` as the stamp (module docstring). Numba's locator interface, by its methods.

    Parameters
    ----------
    inner : object
        The locator Numba would use (one of :data:`LOCATORS`).
    py_file : str
        The kernel's module file.
    """

    def __init__(self, inner, py_file):
        self.inner = inner
        self.py_file = py_file

    def ensure_cache_path(self):
        self.inner.ensure_cache_path()

    def get_cache_path(self):
        return self.inner.get_cache_path()

    def get_disambiguator(self):
        return self.inner.get_disambiguator()

    def get_source_stamp(self):
        return "vfit-" + source_stamp(self.py_file)

    @classmethod
    def from_function(cls, py_func, py_file):
        if py_func.__code__ not in _STAMPED:
            return None  # another library's or the user's function: Numba's locators as usual
        for other in LOCATORS:
            inner = None if other is cls else other.from_function(py_func, py_file)
            if inner is not None:
                return cls(inner, py_file)
        return None


#: Numba's list of cache locators, first to last, shared by its cache kinds (its one hook for a locator of one's
#: own); this module's goes first. (``NUMBA_CACHE_LOCATOR_CLASSES``, if a user sets it, replaces the list.)
LOCATORS = caching.CompileResultCacheImpl._locator_classes
if StampedLocator not in LOCATORS:
    LOCATORS.insert(0, StampedLocator)


prange = numba.prange
