"""The fixed-order dot product (compute.fixed_order.dot) against numba's np.dot (a BLAS ddot),
one thread, on vectors of the lengths an MPRGP solve meets (a few hundred to tens of thousands of
contacts). Each figure is the least of three timed loops of many calls inside numba, after a
warm-up, so no Python call overhead is counted.

    python benchmarks/fixed_order_dot.py [--sizes 500 5000 35000]

Prints a Markdown table (µs per call); the figures are quoted in
benchmarks/results/machine_determinism.md.
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numba  # noqa: E402
import numpy as np  # noqa: E402

from compute.fixed_order import dot  # noqa: E402


@numba.njit
def _blas(x, y):
    return np.dot(x, y)


@numba.njit
def _repeat(f, x, y, k):
    s = 0.0
    for _ in range(k):
        s += f(x, y)
    return s


def per_call(f, x, y, calls: int) -> float:
    """Least seconds per call over three loops of ``calls`` calls."""
    _repeat(f, x, y, 1)
    best = np.inf
    for _ in range(3):
        t = time.perf_counter()
        _repeat(f, x, y, calls)
        best = min(best, (time.perf_counter() - t) / calls)
    return best


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--sizes", type=int, nargs="+", default=[500, 5000, 35000])
    a = p.parse_args()
    rng = np.random.default_rng(0)
    print("| n | BLAS ddot µs | fixed order µs | ratio |\n|---|---|---|---|")
    for n in a.sizes:
        x, y = rng.normal(size=n), rng.normal(size=n)
        calls = max(20_000_000 // n, 100)
        blas, fixed = per_call(_blas, x, y, calls), per_call(dot, x, y, calls)
        print(f"| {n} | {blas * 1e6:.2f} | {fixed * 1e6:.2f} | {fixed / blas:.2f} |")


if __name__ == "__main__":
    main()
