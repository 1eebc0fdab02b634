"""``vfit batch``: every garment of a job on every body, on a Dask cluster, into a resumable results table."""
import click

from ._common import handle_errors, interruption

#: Exit code of a batch that finished with failed tasks (their rows say why).
SOME_FAILED = 5


class TaskProgress:
    """A bar over the tasks on a terminal (rewritten in place), else a line per task."""

    def __init__(self, quiet):
        import sys
        import time

        self.quiet = quiet
        self.stream = sys.stderr
        self.tty = self.stream.isatty()
        self.t0 = time.perf_counter()
        self.counts = {"ok": 0, "not_converged": 0, "failed": 0}

    def __call__(self, done, todo, row):
        import time

        if self.quiet:
            return
        self.counts[row["status"]] = self.counts.get(row["status"], 0) + 1
        wall = time.perf_counter() - self.t0
        left = wall / done * (todo - done)
        counts = ", ".join(f"{n} {s.replace('_', ' ')}" for s, n in self.counts.items() if n)
        if self.tty:
            width = 24
            bar = "#" * round(width * done / todo) + "." * (width - round(width * done / todo))
            text = (f"\r[{bar}] {done}/{todo} tasks ({counts}), {60 * done / wall:.1f} drapes/min, "
                    f"~{_duration(left)} left\033[K")
            click.echo(text, file=self.stream, nl=done == todo)
        else:
            what = f"{row['garment_name']}{' ' + row['size'] if row['size'] else ''} on {row['body']}"
            err = f": {row['error']}" if row["status"] == "failed" else ""
            click.echo(f"vfit batch: {done}/{todo} {what}: {row['status']}{err} ({row['task_s'] or 0:.1f} s on "
                       f"{row['worker']}; ~{_duration(left)} left)", file=self.stream)


def _duration(s):
    return f"{s:.0f} s" if s < 90 else f"{s / 60:.0f} min" if s < 5400 else f"{s / 3600:.1f} h"


@click.command()
@click.argument("job_file", metavar="JOB", type=click.Path(dir_okay=False))
@click.option("-o", "--output", "outdir", default="batch_out", show_default=True, type=click.Path(file_okay=False),
              help="Output directory: results.parquet (and meshes/, bodies/ with --keep-meshes), summary.json.")
@click.option("--workers", type=click.IntRange(1, 1024), default=None,
              help="Worker processes of the local Dask cluster [default: the cores available].")
@click.option("--scheduler", default=None, metavar="ADDRESS",
              help="Run on the Dask cluster whose scheduler is at ADDRESS (e.g. tcp://10.0.0.5:8786) instead of "
                   "a local one; its workers need vfit installed.")
@click.option("--retries", type=click.IntRange(0, 100), default=2, show_default=True,
              help="How many deaths of its worker a task survives (rescheduled elsewhere), and re-runs of a task "
                   "that raised an unexpected error. A drape that fails on its input is not retried.")
@click.option("--keep-meshes", is_flag=True,
              help="Also write each drape: meshes/TASK/final.obj and fit.ply, bodies/BODY.obj (metres, Y up).")
@click.option("--retry-failed", is_flag=True, help="Run again the tasks whose row says failed.")
@click.option("-q", "--quiet", is_flag=True, help="No progress and no summary (errors only).")
@click.pass_context
@handle_errors
def batch(ctx, job_file, outdir, workers, scheduler, retries, keep_meshes, retry_failed, quiet):
    """Drape every garment of JOB (.json/.yaml) on every body of it, on Dask.

    \b
    JOB lists garments and bodies (paths relative to JOB):
      garments:
        - suits/male_casualsuit02.obj
        - {path: shirt.obj, material: jersey, sizes: [S, M, L]}
        - {path: tee.json, spacing: 25}       # a sewing pattern (GarmentCode JSON)
        - {path: pieces.dxf, seams: pieces.seams.json}   # DXF-AAMA + seams
      bodies:
        - {name: anna, gender: female, height: 168, waist: 72, hips: 98}
        - {gender: male}
        - customers.csv    # name, gender, height, weight, bust, waist, hips, ...
      drape: {frames: 600, collider: mesh}      # optional, for every task

    The tasks are garments x sizes x bodies; a garment with sizes is graded
    to each (as vfit size does) and draped at that size. A sewing pattern is
    sewn and draped as vfit drape PATTERN does (no sizes; its row adds its
    worst seam's gap, mm, and worst panel's strain p99, %). Each finished task
    is a row of OUTDIR/results.parquet (inputs, status ok / not_converged /
    failed and why, surface penetration, yarn strain, ease and verdict per
    body region, timings, worker), written as it finishes: a re-run of the
    same JOB skips the tasks that have a row, and a crash loses nothing
    already done. A worker that dies mid-task costs a retry elsewhere, not a
    row. Exit 0 when every task has a row and none failed, 5 when some
    failed (listed at the end), 2 for a bad JOB.

    \b
    Examples:
      vfit batch job.yaml -o out/ --workers 2
      vfit batch job.yaml -o out/ --scheduler tcp://head:8786 --keep-meshes
    """
    from ._outdir import OutdirLock, check_outdir, check_outputs

    check_outdir(outdir)
    check_outputs(outdir, ("summary.json",), {"JOB": job_file})
    if scheduler is not None and workers is not None:
        raise click.UsageError("give either --workers (a local cluster) or --scheduler (an existing one), not both")
    try:
        with OutdirLock(outdir):
            code = _batch(job_file, outdir, workers, scheduler, retries, keep_meshes, retry_failed, quiet)
    except KeyboardInterrupt as exc:  # Ctrl-C or SIGTERM (the vfit group's)
        name, code = interruption(exc)
        click.echo(f"Error: interrupted by {name}; the rows written so far stay in {outdir}/results.parquet "
                   "(run the job again to go on)", err=True)
    if code:
        ctx.exit(code)


def _batch(job_file, outdir, workers, scheduler, retries, keep_meshes, retry_failed, quiet):
    """The batch's work inside its held OUTDIR; returns the exit code."""
    import os

    from vfit_engine.batch.job import load_job
    from vfit_engine.batch.runner import run_batch

    from ._common import write_json

    job = load_job(job_file)
    for w in job.warnings:
        click.echo(f"Warning: {job_file}: {w}", err=True)

    def start(todo):
        if not quiet:
            where = f"the Dask cluster at {scheduler}" if scheduler else "a local Dask cluster"
            click.echo(f"vfit batch: {len(job.tasks)} tasks ({job.garments} garments x {job.bodies} bodies"
                       f"{', with sizes' if any(t.size for t in job.tasks) else ''}); {len(job.tasks) - todo} done "
                       f"already" + (f", running {todo} on {where}" if todo else ", nothing to run"), err=True)

    s = run_batch(job, outdir, workers=workers, scheduler=scheduler, retries=retries, keep_meshes=keep_meshes,
                  retry_failed=retry_failed, on_start=start, on_task=TaskProgress(quiet))
    summary = dict(job=os.path.abspath(job_file), tasks=s.tasks, counts=s.counts, ran=s.ran, skipped=s.skipped,
                   wall_s=round(s.wall_s, 3), workers=s.workers, drapes_per_hour=round(s.drapes_per_hour, 1),
                   failures=[dict(task=t, error=e) for t, e in s.failures],
                   results=os.path.join(outdir, "results.parquet"))
    write_json(os.path.join(outdir, "summary.json"), summary)
    if not quiet:
        counts = ", ".join(f"{n} {k.replace('_', ' ')}" for k, n in s.counts.items())
        rate = (f" in {s.wall_s:.1f} s on {s.workers} worker{'s' if s.workers != 1 else ''}, "
                f"{s.drapes_per_hour:.0f} drapes/hour" if s.ran else "")
        click.echo(f"vfit batch: {s.tasks} tasks: {counts}; ran {s.ran}{rate}, skipped {s.skipped} done before")
        for task, error in s.failures:
            click.echo(f"  failed: {task}: {error}")
        click.echo(f"results: {summary['results']}")
    return SOME_FAILED if s.counts.get("failed") else 0
