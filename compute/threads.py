"""Threads of the parallel numba kernels (loops over the bodies of a group).

``configure(n)`` must run before the first parallel kernel: it picks numba's threading layer
and the number of threads. OpenMP (numba's "omp" layer, GNU libgomp) lets idle threads spin
for a while before they sleep, which steals a shared core from other jobs; with
``OMP_WAIT_POLICY=passive`` they sleep at once. Measured (benchmarks/results/threads.md, the
144-disk mixture): beside one busy process, 2 spinning threads took 12.5 s against 6.4 s
passive and 6.7 s with one thread; alone the three are within noise (6.4 to 7.0 s). Passive
OpenMP is the default; numba's "workqueue" layer was no better. On the paper's size the
parallel kernels matter more (benchmarks/results/soft_step_cost_scaling_t{1,2}.md: 1500 T6
disks, 3.5 s per step on one thread, 3.0 s on two; the contact solve, serial, is most of it).
"""

from __future__ import annotations

import os


def configure(threads: int | None = None) -> int:
    """Use ``threads`` threads (default: NUMBA_NUM_THREADS or every core); returns the number set."""
    os.environ.setdefault("OMP_WAIT_POLICY", "passive")
    import numba

    if threads is None:
        return numba.config.NUMBA_NUM_THREADS
    if not 1 <= threads <= numba.config.NUMBA_NUM_THREADS:
        raise ValueError(f"threads: expected 1..{numba.config.NUMBA_NUM_THREADS} (the cores numba may use), "
                         f"got {threads}")
    numba.set_num_threads(threads)
    return threads
