"""The worker processes of a size run or a batch: spawned, one Numba thread each, warmed up, ended on an error.

:func:`worker_pool` starts them (:func:`vfit_engine.process_cache.warm_up` in each), :func:`pool_results` yields
the jobs' results as they finish, a job whose process died as a failure the caller words.
"""
from __future__ import annotations

import contextlib
import multiprocessing
import os
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool

from vfit_engine import process_cache


def default_workers():
    """The cores this process may use."""
    try:
        return max(len(os.sched_getaffinity(0)), 1)
    except AttributeError:  # not Linux
        return max(os.cpu_count() or 1, 1)


@contextlib.contextmanager
def worker_pool(n_workers):
    """A pool of ``n_workers`` spawned processes with one Numba thread each, warmed up
    (:func:`vfit_engine.process_cache.warm_up`); None for one worker (the jobs then run in this process).
    On an error or an interruption the workers are ended at once, not waited for."""
    if n_workers <= 1:
        yield None
        return

    # a spawned child inherits the environment as it is when it starts (Numba reads the setting when
    # it is imported there); the processes start at the submits, so it covers them all and is put
    # back at once
    key, before = "NUMBA_NUM_THREADS", os.environ.get("NUMBA_NUM_THREADS")
    pool = ProcessPoolExecutor(n_workers, mp_context=multiprocessing.get_context("spawn"))
    ok = False
    try:
        os.environ[key] = "1"
        try:
            for _ in range(n_workers):
                pool.submit(process_cache.warm_up)
        finally:
            if before is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = before
        yield pool
        ok = True
    finally:
        if not ok:
            _end_workers(pool)
        pool.shutdown(wait=True, cancel_futures=True)


def _end_workers(pool):
    """Terminate the pool's worker processes (this pool's own, by their process objects)."""
    end = getattr(pool, "terminate_workers", None)  # Python >= 3.14
    if end is not None:
        end()
        return
    for proc in list((getattr(pool, "_processes", None) or {}).values()):
        if proc.is_alive():
            proc.terminate()


def pool_results(futures, failed):
    """The results of submitted jobs (``futures``: future -> job), as they finish; a job whose process died
    gives ``failed(job, message)``."""
    for f in as_completed(futures):
        try:
            yield f.result()
        except BrokenProcessPool as exc:
            yield failed(futures[f], f"its worker process died ({exc})")
