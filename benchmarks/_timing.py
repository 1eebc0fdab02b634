"""Timing helpers shared by the benchmark scripts (run as ``python benchmarks/bench_*.py``)."""
import time

import numpy as np


def median_ms(fn, repeat):
    """Median wall time of ``repeat`` calls of ``fn()``, in milliseconds."""
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return 1000 * float(np.median(times))
