"""Running a batch on Dask distributed: a local cluster, or any cluster by its scheduler's address.

::

    job = load_job("job.yaml")
    summary = run_batch(job, "out/", workers=2)                 # a LocalCluster of 2 processes
    summary = run_batch(job, "out/", scheduler="tcp://head:8786")   # the same code path on a cluster

What it promises (and why it is built so):

- **Nothing done is lost.** The client writes each task's row the moment its future completes
  (:class:`vfit_engine.batch.results.ResultStore`: one atomic part file per row), so killing the
  client loses at most the tasks still running. Meshes (``keep_meshes``) come back as bytes and the
  client writes them too: remote workers need no shared file system.
- **Resumable.** Tasks whose id already has a row are not submitted; when none is left no cluster is
  started at all (a re-run of a finished job takes as long as reading its results).
- **A killed worker costs a retry, not a row.** Dask reschedules the tasks of a worker that died on
  another one; ``retries`` sets how many deaths a task survives (the scheduler's
  ``allowed-failures``, for the local cluster) and how many times a task that raised is re-run
  (``Client.submit(retries=...)``). A future completes once, so a task gets one row whatever
  happened to it. A drape that fails on its input returns a ``failed`` row and is not retried.
- **A body is built once**, as a Dask task of its own whose result (300 kB) every drape on that body
  takes as an input: Dask runs those drapes where the body is, or copies it (cheaper than building it
  again: 0.3-2 s). The tasks are submitted body by body, through a window of a few per worker, and a
  body is let go after its last drape.
- **Each worker is one process with one thread** (and one Numba thread: the cloth kernels are the
  work, two threads per process would fight over the same cores) that loads the body model once
  (:mod:`vfit_engine.process_cache`); the cloth kernels load from the Numba cache that every process
  on a machine shares (``NUMBA_CACHE_DIR`` moves it, e.g. for a read-only install).
"""
from __future__ import annotations

import contextlib
import dataclasses
import logging
import threading
import time

import dask
from distributed import Client, LocalCluster, as_completed
from distributed.diagnostics.plugin import WorkerPlugin

from vfit_engine import process_cache
from vfit_engine.batch.results import ResultStore, flat_row
from vfit_engine.batch.task import blank_row, build_body, run_task
from vfit_engine.errors import InputError
from vfit_engine.worker_pool import default_workers

#: Environment of the local cluster's worker processes (read when they import Numba / BLAS).
WORKER_ENV = {"NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
#: Dask settings of the local cluster. The workers' statistical profiler samples the running task every
#: 10 ms from a thread of its own, which competes with the drapes when every core runs one.
DASK_CONFIG = {"distributed.worker.profile.enabled": False}
#: Where the local cluster's scheduler serves its HTTP routes (health, metrics; no dashboard): a free port on
#: this machine, so that clusters started side by side never compete for Dask's default 8787.
SCHEDULER_HTTP = "127.0.0.1:0"
#: Seconds to wait for a scheduler given by address.
CONNECT_TIMEOUT_S = 20


@dataclasses.dataclass
class Summary:
    """The outcome of :func:`run_batch`: counts per status over the job's tasks, what this run did."""

    tasks: int
    counts: dict
    ran: int
    skipped: int
    wall_s: float
    workers: int
    failures: list  # (task label, error) of this job's failed rows, at most 10

    @property
    def drapes_per_hour(self):
        return 3600.0 * self.ran / self.wall_s if self.ran and self.wall_s > 0 else 0.0


def _warm_up():
    """Load the body model and kernels in a thread of a fresh worker (its first task waits for the lock in
    :mod:`vfit_engine.process_cache` instead of loading them twice)."""
    threading.Thread(target=process_cache.warm_up, name="vfit-warm-up", daemon=True).start()


def _plugin():
    class WarmUp(WorkerPlugin):
        name = "vfit-warm-up"

        def setup(self, worker):
            _warm_up()

    return WarmUp()


def local_cluster(n_workers):
    """A LocalCluster of ``n_workers`` processes of one thread (and one Numba thread) each, no dashboard,
    only its errors logged (a worker's death is a retry, reported in the task's row if it matters).

    Without a dashboard Dask's scheduler still serves its health and metrics routes over HTTP, on port 8787
    unless told otherwise: a second cluster on the machine (another batch, a test) then warned "Port 8787 is
    already in use". It listens on a free local port instead (``SCHEDULER_HTTP``)."""
    return LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True, dashboard_address=None,
                        scheduler_kwargs={"dashboard_address": SCHEDULER_HTTP}, silence_logs=logging.ERROR,
                        env=dict(WORKER_ENV))


@contextlib.contextmanager
def connect(workers=None, scheduler=None, retries=2):
    """A Dask client: on the scheduler at ``scheduler`` (an address), else on a LocalCluster of ``workers``
    processes (None: the cores). Yields (client, number of workers)."""
    with dask.config.set(dict(DASK_CONFIG, **{"distributed.scheduler.allowed-failures": int(retries)})):
        if scheduler:
            try:
                client = Client(scheduler, timeout=f"{CONNECT_TIMEOUT_S}s", set_as_default=False)
            except (OSError, TimeoutError) as exc:
                raise InputError(f"cannot reach the Dask scheduler at {scheduler} ({exc}); start one with "
                                 "'dask scheduler' and workers with 'dask worker ADDRESS' (README: Batches)") from None
            with client:
                yield client, len(client.scheduler_info()["workers"])
            return

        n = int(workers or default_workers())
        with local_cluster(n) as cluster, Client(cluster, set_as_default=False) as client:
            yield client, n


def run_batch(job, outdir, workers=None, scheduler=None, retries=2, keep_meshes=False, retry_failed=False,
              on_start=None, on_task=None, client=None):
    """Run the tasks of ``job`` (:class:`vfit_engine.batch.job.Job`) that have no row in ``outdir`` yet.

    Parameters
    ----------
    job : Job
    outdir : str or Path
        Where ``results.parquet`` (and with ``keep_meshes`` ``meshes/`` and ``bodies/``) are.
    workers : int or None
        Worker processes of the local cluster (None: the cores); not used with ``scheduler``.
    scheduler : str or None
        Address of a running Dask scheduler (``tcp://host:8786``).
    retries : int
        Deaths of its worker a task survives, and re-runs of a task that raised.
    keep_meshes : bool
    retry_failed : bool
        Also run again the tasks whose row is ``failed``.
    on_start : callable or None
        ``on_start(todo)`` with the number of tasks to run, before a cluster is reached.
    on_task : callable or None
        ``on_task(done, todo, row)`` after each task's row is written (``row``: the flat row).
    client : distributed.Client or None
        Use this client (tests, notebooks) instead of connecting.

    Returns
    -------
    Summary
    """
    t0 = time.perf_counter()
    store = ResultStore(outdir)
    before = store.statuses()
    todo = [t for t in job.tasks if t.id not in before or (retry_failed and before[t.id] == "failed")]
    if on_start is not None:
        on_start(len(todo))
    n_workers = 0
    if todo:
        todo.sort(key=lambda t: (t.body_key(), t.garment, t.size or ""))
        if client is not None:
            n_workers = len(client.scheduler_info()["workers"])
            _run(client, todo, store, retries, keep_meshes, on_task)
        else:
            with connect(workers, scheduler, retries) as (c, n_workers):
                _run(c, todo, store, retries, keep_meshes, on_task)
    return _summary(job, store, len(todo), time.perf_counter() - t0, n_workers)


def _run(client, todo, store, retries, keep_meshes, on_task):
    """Submit ``todo`` in order through a window of :func:`_window` tasks (a million futures at once would
    hold the client's and the scheduler's memory for nothing) and write each row as its task finishes."""
    client.register_plugin(_plugin())
    queue, futures, bodies = iter(todo), {}, {}

    def submit():
        task = next(queue, None)
        if task is None:
            return None
        payload = task.payload(keep_meshes)
        key = task.body_key()
        if key not in bodies:  # a body is a task of its own: built once, handed to every drape on it
            bodies[key] = [client.submit(build_body, payload["body"], key=f"vfit-body-{key}", pure=False,
                                         retries=retries), 0]
        bodies[key][1] += 1
        fut = client.submit(run_task, payload, bodies[key][0], key=f"vfit-task-{task.id}", pure=False,
                            retries=retries)
        futures[fut] = task
        return fut

    window = as_completed([submit() for _ in range(min(len(todo), _window(client)))], loop=client.loop)
    try:
        for done, fut in enumerate(window, start=1):
            task = futures.pop(fut)
            following = submit()
            if following is not None:
                window.add(following)
            body = bodies[task.body_key()]
            body[1] -= 1
            if body[1] == 0:  # its last drape (the tasks come body by body): the body may go
                del bodies[task.body_key()]
            try:
                row = fut.result()
            except Exception as exc:  # the task raised after its retries, or its workers kept dying
                row = blank_row(task.payload(), _why(exc, retries))
            fut.release()
            meshes = row.pop("meshes", None)
            if meshes:
                row["final_mesh"], row["body_mesh"] = store.keep_meshes(task, meshes)
            flat = flat_row(row, task)
            store.add([flat])
            if on_task is not None:
                on_task(done, len(todo), flat)
    finally:
        client.cancel(list(futures))  # Ctrl-C or an error: the rest stops; the rows written stay
        store.flush()


def _window(client):
    """Tasks in flight: enough to keep every worker busy (and its next tasks queued), at least 64."""
    return max(64, 4 * len(client.scheduler_info()["workers"]))


def _why(exc, retries):
    name = type(exc).__name__
    if name == "KilledWorker":
        return f"its worker died {retries + 1} times running it (a crash or out of memory; see the workers' logs)"
    return f"{name}: {exc} (after {retries} retries)"


def _summary(job, store, ran, wall_s, n_workers):
    table = store.read(["task_id", "status", "error"])
    mine = {t.id: t for t in job.tasks}
    counts, failures = {"ok": 0, "not_converged": 0, "failed": 0}, []
    for tid, status, error in zip(*(table.column(c).to_pylist() for c in ("task_id", "status", "error"))):
        if tid not in mine:
            continue
        counts[status] = counts.get(status, 0) + 1
        if status == "failed" and len(failures) < 10:
            t = mine[tid]
            failures.append((f"{t.garment_name}{' ' + t.size if t.size else ''} on {t.body_label}", error))
    return Summary(tasks=len(job.tasks), counts=counts, ran=ran, skipped=len(job.tasks) - ran, wall_s=wall_s,
                   workers=n_workers, failures=failures)
