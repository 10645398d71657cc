"""Threads of the parallel numba kernels (loops over the bodies of a group).

``configure(n)`` runs before the first parallel kernel: it sets the most threads a run may use
and OpenMP's wait policy. numba's "omp" layer (GNU libgomp) lets idle threads spin before they
sleep, which steals a shared core from other jobs: beside a busy process, spinning threads
nearly double a run's time while passive ones cost almost nothing alone
(benchmarks/results/threads.md). Passive threads are the default (a user's OMP_WAIT_POLICY or
GOMP_SPINCOUNT wins); numba's "workqueue" layer was slower.

A passive pool pays a wake-up for every parallel kernel launch (about 50 µs here, against 2 µs
with one thread), which a small group of bodies does not earn back: ``for_bodies(n)`` gives a
group one thread per ``MIN_BODIES_PER_THREAD`` bodies, up to the configured number (with 74
soft bodies, the 144-disk mixture ran 6.75 s on two passive threads against 6.35 s on one
before this rule).
"""

from __future__ import annotations

import functools
import os

MIN_BODIES_PER_THREAD = 200
_max_threads: int | None = None


def configure(threads: int | None = None) -> int:
    """Use at most ``threads`` threads (default: NUMBA_NUM_THREADS or every core); returns it."""
    global _max_threads
    if "OMP_WAIT_POLICY" not in os.environ and "GOMP_SPINCOUNT" not in os.environ:  # the user's choice wins
        os.environ["OMP_WAIT_POLICY"] = "passive"
    import numba

    available = numba.config.NUMBA_NUM_THREADS
    if threads is not None and not 1 <= threads <= available:
        raise ValueError(f"threads: expected 1..{available} (the cores numba may use), got {threads}")
    _max_threads = threads or available
    return _max_threads


def for_bodies(n: int) -> None:
    """Set the threads of the next parallel kernels (in this thread) for a group of n bodies."""
    import numba

    most = _max_threads or numba.config.NUMBA_NUM_THREADS
    numba.set_num_threads(max(1, min(most, n // MIN_BODIES_PER_THREAD)))


def sized_to_group(method):
    """Decorator of a body group's methods that launch parallel kernels: threads per
    :func:`for_bodies` of the group's size (``len(self)``)."""
    @functools.wraps(method)
    def wrapper(self, *args, **kwargs):
        for_bodies(len(self))
        return method(self, *args, **kwargs)
    return wrapper
