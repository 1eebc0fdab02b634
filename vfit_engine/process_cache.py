"""What a worker process keeps between its jobs: the body model, the bodies it built, their fit tables.

A size run (:mod:`vfit_engine.sizes`) and a batch (:mod:`vfit_engine.batch`) send many drapes to a few
long-lived processes. Loading the body model (~0.5 s), solving a body to measurements (0.3-1 s) and
slicing a body's girth planes for the fit table (~0.2 s) are the same for every drape on that body, so
each process does them once and keeps them here::

    model = process_cache.model()
    body = process_cache.body(("female", 1.68, 0.72), lambda: resolve_body(model, targets=...))
    table = process_cache.fit_table(model, body)

Bodies are kept by the caller's key (a batch's canonical spec), the last :data:`MAX_BODIES` of them:
a batch runs the tasks of one body together, so a small cache builds each body once per process.
A lock makes the cache safe to fill from a warm-up thread while the first job waits for it.
"""
from __future__ import annotations

import collections
import hashlib
import os
import threading

import numpy as np
import scipy.optimize  # noqa: F401  (warm_up: a body's solve)

from vfit_engine.body.model import BodyModel
from vfit_engine.body.morph import Morpher  # noqa: F401  (warm_up: loaded with this module, once per process)
from vfit_engine.drape import prepare_drape, run_drape  # noqa: F401
from vfit_engine.fit.table import FitTable
from vfit_engine.kernels import cloth  # noqa: F401

#: Bodies (and their fit tables) kept per process, most recently used first.
MAX_BODIES = 8

_LOCK = threading.RLock()
_MODEL = []
_BODIES = collections.OrderedDict()
_TABLES = collections.OrderedDict()


def model():
    """The body model, loaded once per process."""
    with _LOCK:
        if not _MODEL:
            _MODEL.append(BodyModel.load())
        return _MODEL[0]


def _kept(store, key, build):
    with _LOCK:
        if key in store:
            store.move_to_end(key)
            return store[key], False
    value = build()  # outside the lock: a warm-up thread must not wait for a body
    with _LOCK:
        store[key] = value
        while len(store) > MAX_BODIES:
            store.popitem(last=False)
    return value, True


def body(key, build):
    """The body kept under ``key`` (hashable), built by ``build()`` the first time; returns (body, built)."""
    return _kept(_BODIES, key, build)


def fit_table(model, body):
    """The body's FitTable (:class:`vfit_engine.fit.table.FitTable`: its girth planes, built once per body)."""
    key = hashlib.sha1(np.ascontiguousarray(body.verts).tobytes()).hexdigest()
    return _kept(_TABLES, key, lambda: FitTable(body, model))[0]


def warm_up():
    """Load what every drape needs in a fresh process: the body model, the drape's modules, the cloth
    kernels from Numba's cache (so the first job's timings are the drape's, not the start's)."""
    model()  # the modules a drape needs are this module's imports
    return os.getpid()
