"""When vfit's Numba kernels compile: as it happens (:func:`watching_compiles`), or ahead (:func:`is_cached`).

A kernel compiles on its first call when its code is not in Numba's cache or is stale there (its sources
changed: :mod:`vfit_engine._jit`), for a minute or more for the cloth's; later runs load it in milliseconds.
A command shows that wait where it happens; the engine itself prints nothing. Importing this module imports
numba.
"""
import contextlib
import sys

from numba.core import caching, event


def is_cached(kernel):
    """Whether ``kernel`` (a function of :func:`vfit_engine._jit.njit`) has code in Numba's cache that is
    fresh for its sources: a look at its index file (milliseconds), for a caller that must know before a run
    whether it will compile (a process pool's workers compile out of :func:`watching_compiles`' sight).

    Parameters
    ----------
    kernel : numba dispatcher

    Returns
    -------
    bool
        False when not cached, stale, or unknown.
    """
    try:  # Numba has no public call for it: the index of a cache of the kernel, empty when missing or stale
        return bool(caching.FunctionCache(kernel.py_func)._cache_file._load_index())
    except Exception:  # moved internals, an unreadable index: not known to be cached, so a compile may come
        return False


class _CompileListener(event.Listener):
    """Numba's compile events, outermost only (a kernel compiles the kernels it calls within its own compile;
    Numba compiles one function at a time, under its compiler lock)."""

    def __init__(self, on_start, on_end):
        self.on_start_, self.on_end_ = on_start, on_end
        self.depth = 0

    def on_start(self, ev):
        self.depth += 1
        if self.depth == 1:
            self.on_start_()

    def on_end(self, ev):
        if self.depth == 0:
            return  # a compile that started before the listener was installed
        self.depth -= 1
        if self.depth == 0:
            # called while a failed compile's exception is on its way out (Numba's Event.is_failed is inverted)
            self.on_end_(sys.exc_info()[0] is None)


@contextlib.contextmanager
def watching_compiles(on_start, on_end):
    """Within the context, call ``on_start()`` when a kernel starts compiling (its cached code is missing or
    stale) and ``on_end()`` when it is compiled, so that a caller can show the wait where it happens.

    Parameters
    ----------
    on_start, on_end : callable
        Called in the compiling thread, ``on_start()`` and ``on_end(done)``, ``done`` False when the compile
        failed or was interrupted (Ctrl-C); a kernel loaded from the cache calls neither.
    """
    with event.install_listener("numba:compile", _CompileListener(on_start, on_end)):
        yield
