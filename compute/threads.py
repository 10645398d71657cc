"""Threads of the parallel numba kernels (loops over the bodies of a group).

``configure(n)`` runs before the first parallel kernel: it sets the most threads a run may use
and OpenMP's wait policy. numba's "omp" layer (GNU libgomp) lets idle threads spin before they
sleep, which steals a shared core from other jobs: beside a busy process, spinning threads
nearly double a run's time while passive ones cost almost nothing alone
(benchmarks/results/threads.md). Passive threads are the default (a user's OMP_WAIT_POLICY or
GOMP_SPINCOUNT wins); numba's "workqueue" layer was slower.

A passive pool pays a wake-up for every parallel kernel launch, many times a one-thread
launch (benchmarks/results/threads.md), which a small group of bodies does not earn back:
``for_bodies(n)`` gives a group one thread per ``MIN_BODIES_PER_THREAD`` bodies, up to the
configured number (the 144-disk mixture's 74 soft bodies ran slower on two passive threads
than on one before this rule: benchmarks/results/design_figures.md).

``configure(n)`` also caps the BLAS pools (OpenBLAS, MKL; threadpoolctl) to n threads. Why: OpenBLAS
threads even a dot product of a few thousand entries, and its idle threads busy-wait, taking a
core from the run beside it (benchmarks/results/threads.md). The contact kernels called it
through numba's ``np.dot`` until their sums were put in a fixed order (compute.fixed_order);
the interior-point solvers and the block solver's least-squares step still call it. The study dispatcher's runs had the cap
already, from the environment it gives them (OPENBLAS_NUM_THREADS); a run started by hand or
from Python did not. A run given more threads by ``OUT/threads`` (below) keeps its BLAS pool.

A run may be given more threads while it runs (:class:`ThreadsFile`): it reads an optional file
``OUT/threads`` (one integer) after every step and, when it changed, calls ``configure`` again
with it (capped to NUMBA_NUM_THREADS, the pool numba started with). Why: a study dispatcher
(studies.dispatch) starts each run with one thread, so that the runs fill the cores; once fewer
runs remain than cores, it writes each remaining run's share of the freed cores there instead of
leaving them idle. ``configure`` only sets the cap that ``for_bodies`` applies at every kernel
launch, so the change takes effect at the next body-group kernel. The kernels are per body (no
reduction across bodies), so a run's results do not depend on its thread count
(tests/compute/test_threads_file.py checks it bit for bit).
"""

from __future__ import annotations

import functools
import os
from pathlib import Path

MIN_BODIES_PER_THREAD = 200
THREADS_FILE = "threads"  # OUT/threads: the most threads a run may use from its next step
_max_threads: int | None = None


def configure(threads: int | None = None, blas: bool = True) -> int:
    """Use at most ``threads`` threads (default: NUMBA_NUM_THREADS or every core) in the parallel
    kernels, and, when ``threads`` is given and ``blas``, in the BLAS pools too; returns it."""
    global _max_threads
    if "OMP_WAIT_POLICY" not in os.environ and "GOMP_SPINCOUNT" not in os.environ:  # the user's choice wins
        os.environ["OMP_WAIT_POLICY"] = "passive"
    import numba

    available = numba.config.NUMBA_NUM_THREADS
    if threads is not None and not 1 <= threads <= available:
        raise ValueError(f"threads: expected 1..{available} (the cores numba may use), got {threads}")
    _max_threads = threads or available
    if threads is not None and blas:
        _limit_blas(threads)
    return _max_threads


def _limit_blas(threads: int) -> None:
    """Cap every loaded BLAS pool to ``threads`` (module docstring), scipy's included: numba's
    kernels call the OpenBLAS of ``scipy.linalg.cython_blas`` (the block solver's np.linalg.lstsq),
    which loads only when imported."""
    import scipy.linalg.cython_blas  # noqa: F401  (loads the BLAS numba's kernels call)
    from threadpoolctl import threadpool_limits

    threadpool_limits(limits=threads, user_api="blas")


def configured() -> int:
    """The most threads a run may use now (configure's, else NUMBA_NUM_THREADS)."""
    import numba

    return _max_threads or numba.config.NUMBA_NUM_THREADS


class ThreadsFile:
    """``OUT/threads``, followed by a running run: ``poll()`` after every step costs one stat;
    the file is read only when its inode, size or modification time changed (it is replaced
    atomically by its writer, compute.files.write_text), and ``configure`` is called when the
    number in it differs from the current one. A missing file changes nothing; a file that is not
    one positive integer is logged and ignored; a number above NUMBA_NUM_THREADS is capped to it."""

    def __init__(self, out: str | Path, log=None):
        self.path = Path(out) / THREADS_FILE
        self.log = log or (lambda msg: None)
        self._seen: tuple | None = None

    def poll(self) -> int | None:
        """The new number of threads when it changed (and was applied), else None."""
        try:
            st = os.stat(self.path)
        except OSError:  # absent (the usual case), or unreadable folder: keep the threads
            self._seen = None
            return None
        key = (st.st_ino, st.st_size, st.st_mtime_ns)
        if key == self._seen:
            return None
        self._seen = key
        try:
            text = self.path.read_text().strip()
            wanted = int(text)
            if wanted < 1:
                raise ValueError(text)
        except (OSError, ValueError) as exc:
            self.log(f"warning: {self.path}: expected one positive integer (threads), got {exc}; ignored")
            return None
        import numba

        n = min(wanted, numba.config.NUMBA_NUM_THREADS)
        if n == configured():
            return None
        before = configured()
        configure(n, blas=False)  # the BLAS pool stays as the run started: more of it is not measured
        self.log(f"threads: {before} -> {n} ({self.path}"
                 + (f" asks {wanted}, NUMBA_NUM_THREADS is {n})" if wanted != n else ")"))
        return n


def for_bodies(n: int) -> None:
    """Set the threads of the next parallel kernels (in this thread) for a group of n bodies."""
    import numba

    numba.set_num_threads(max(1, min(configured(), n // MIN_BODIES_PER_THREAD)))


def sized_to_group(method):
    """Decorator of a body group's methods that launch parallel kernels: threads per
    :func:`for_bodies` of the group's size (``len(self)``)."""
    @functools.wraps(method)
    def wrapper(self, *args, **kwargs):
        for_bodies(len(self))
        return method(self, *args, **kwargs)
    return wrapper
