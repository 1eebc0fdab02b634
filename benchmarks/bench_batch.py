"""Throughput of ``vfit batch``: the four shared outfits x 10 bodies on 1 and on 2 Dask workers.

Writes a job (the four garments of ``../shared/assets/garments`` x ten bodies given by height and
weight, each built in the garment's gender) and runs it with ``vfit batch`` as a user would, into a
fresh OUTDIR, on a local cluster of 1 worker and then of 2. Reports per run the wall time of the
command (cluster start and shut-down included), drapes per hour, and how much of the wall time the
tasks themselves took (the sum of their ``task_s`` over the workers: the rest is the client, the
scheduler, the cluster's start and idle workers at the end). Then:

- **efficiency** 1 -> 2 workers: throughput(2) / (2 x throughput(1)); beside it the machine's own:
  the first ``--plain`` tasks as ``vfit drape`` processes with one Numba thread, one after the other
  against two shell loops at once (what two drapes at a time cost on these cores without Dask);
- **overhead per task against a plain ``vfit drape``**: the same inputs draped one by one with
  ``vfit drape`` (a process each, as a shell loop would; ``--plain K`` of them, default 8: the four
  garments on the first two bodies), their mean wall time against the batch's cost per task for the
  same tasks (a row's ``task_s`` times the run's wall / sum of ``task_s``: its share of the run, start
  and idle included). With equal means: a 1-worker batch (one process, one Numba thread) against
  ``vfit drape`` with ``NUMBA_NUM_THREADS=1``; a 2-worker batch against ``vfit drape`` on both cores (its
  default), which is what a shell loop over ``vfit drape`` gets from the machine.

    python benchmarks/bench_batch.py [--bodies 10] [--plain 8] [--json]
"""
import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
GARMENTS = ROOT / ".." / "shared" / "assets" / "garments"
NAMES = ("female_casualsuit01", "female_sportsuit01", "male_casualsuit02", "male_casualsuit06")
#: Ten bodies: (height cm, weight kg), the garment's gender (no ``gender`` key: vfit takes the garment's).
BODIES = ((160, 55), (165, 60), (170, 65), (175, 70), (180, 75), (185, 80), (170, 85), (175, 90), (180, 68),
          (168, 72))
VFIT = [sys.executable, "-m", "vfit_cli.main"]


def write_job(folder, n_bodies):
    import yaml

    job = dict(garments=[str((GARMENTS / n / f"{n}.obj").resolve()) for n in NAMES],
               bodies=[dict(name=f"h{h}w{w}", height=h, weight=w) for h, w in BODIES[:n_bodies]])
    path = Path(folder) / "job.yaml"
    path.write_text(yaml.safe_dump(job))
    return path, job


def run_batch(job, outdir, workers):
    import pyarrow.parquet as pq

    t = time.perf_counter()
    proc = subprocess.run(VFIT + ["batch", str(job), "-o", str(outdir), "--workers", str(workers), "--quiet"],
                          capture_output=True, text=True)
    wall = time.perf_counter() - t
    if proc.returncode not in (0, 5):
        raise SystemExit(f"vfit batch failed ({proc.returncode}): {proc.stderr}")
    rows = pq.read_table(outdir / "results.parquet").to_pylist()
    bodies = {r["body_key"]: r["body_s"] or 0.0 for r in rows}  # each body built once, for all its tasks
    busy = sum(r["task_s"] or 0.0 for r in rows) + sum(bodies.values())
    status = {s: sum(r["status"] == s for r in rows) for s in ("ok", "not_converged", "failed")}
    return dict(workers=workers, wall_s=round(wall, 2), tasks=len(rows), drapes_per_hour=round(3600 * len(rows) / wall),
                task_s_sum=round(busy, 2), busy_share=round(busy / (wall * workers), 3), status=status,
                failures=[(r["garment_name"], r["body"], r["status"], r["error"]) for r in rows if r["status"] != "ok"],
                task_s={(Path(r["garment"]).stem, r["body"]): r["task_s"] for r in rows})


def plain_drapes(job, folder, k, threads, streams=1):
    """``vfit drape`` of the first ``k`` tasks (garment-major over the first bodies), one process each, with
    ``threads`` Numba threads (None: its default, the cores), in ``streams`` shell loops at once; returns
    (per drape, wall time of all)."""
    import os
    from concurrent.futures import ThreadPoolExecutor

    env = dict(os.environ)
    if threads:
        env["NUMBA_NUM_THREADS"] = str(threads)
    pairs = [(g, b) for b in job["bodies"] for g in job["garments"]][:k]

    def loop(stream):
        out = []
        for i, (g, b) in enumerate(pairs):
            if i % streams != stream:
                continue
            cmd = VFIT + ["drape", g, "-o", str(Path(folder) / f"plain{stream}"), "--quiet", "--every", "0",
                          "--height", str(b["height"]), "--weight", str(b["weight"])]
            t = time.perf_counter()
            proc = subprocess.run(cmd, capture_output=True, text=True, env=env)
            out.append(dict(garment=Path(g).stem, body=b["name"], wall_s=round(time.perf_counter() - t, 2),
                            exit=proc.returncode))
        return out

    t = time.perf_counter()
    with ThreadPoolExecutor(streams) as pool:
        runs = list(pool.map(loop, range(streams)))
    return [d for r in runs for d in r], time.perf_counter() - t


def overhead(run, plain):
    """The batch's cost per task against the plain drapes of the same tasks: (batch mean, plain mean, ratio-1)."""
    scale = run["wall_s"] / run["task_s_sum"]
    batch = [scale * run["task_s"][(p["garment"], p["body"])] for p in plain]
    b, p = sum(batch) / len(batch), sum(q["wall_s"] for q in plain) / len(plain)
    return dict(workers=run["workers"], batch_mean_s=round(b, 2), plain_mean_s=round(p, 2), overhead=round(b / p - 1, 3))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bodies", type=int, default=10)
    ap.add_argument("--plain", type=int, default=8)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    if not GARMENTS.is_dir():
        raise SystemExit(f"needs the shared garments in {GARMENTS}")
    with tempfile.TemporaryDirectory(prefix="vfit-bench-batch-") as tmp:
        tmp = Path(tmp)
        job_path, job = write_job(tmp, args.bodies)
        runs = [run_batch(job_path, tmp / f"out{w}", w) for w in (1, 2)]
        (seq, seq_wall), (both, _) = (plain_drapes(job, tmp, args.plain, threads) for threads in (1, None))
        _, pair_wall = plain_drapes(job, tmp, args.plain, 1, streams=2)
    one, two = runs
    efficiency = two["drapes_per_hour"] / (2 * one["drapes_per_hour"])
    res = dict(runs=[{k: v for k, v in r.items() if k != "task_s"} for r in runs], efficiency=round(efficiency, 3),
               plain=dict(one_thread=seq, all_cores=both), overhead=[overhead(one, seq), overhead(two, both)],
               machine_efficiency=round(seq_wall / (2 * pair_wall), 3))
    if args.json:
        print(json.dumps(res, indent=1))
        return
    for r in res["runs"]:
        print(f"{r['workers']} worker(s): {r['tasks']} drapes in {r['wall_s']:.1f} s = {r['drapes_per_hour']} drapes/h "
              f"(tasks busy {100 * r['busy_share']:.0f} % of worker time; {r['status']})")
        for f in r["failures"]:
            print(f"  {f[0]} on {f[1]}: {f[2]}: {f[3]}")
    print(f"efficiency 1 -> 2 workers: {100 * efficiency:.1f} %; the machine's own, {args.plain} plain drapes "
          f"(1 Numba thread) one after the other against two at a time: {100 * res['machine_efficiency']:.1f} %")
    for o, what in zip(res["overhead"], ("vfit drape with 1 Numba thread", "vfit drape on all cores")):
        print(f"per task, the same {args.plain} tasks: {o['workers']}-worker batch {o['batch_mean_s']:.2f} s, {what} "
              f"{o['plain_mean_s']:.2f} s: overhead {100 * o['overhead']:+.1f} %")

if __name__ == "__main__":
    main()
