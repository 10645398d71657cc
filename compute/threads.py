"""Threads of the parallel numba kernels (loops over the bodies of a group).

``configure(n)`` must run before the first parallel kernel: it picks numba's threading layer
and the number of threads. OpenMP (numba's "omp" layer, GNU libgomp) lets idle threads spin
for a while before they sleep, which steals a shared core from other jobs; with
``OMP_WAIT_POLICY=passive`` they sleep at once.
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
