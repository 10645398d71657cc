"""MPRGP's stop test (compute.solvers.mprgp._error, one pass over the scaled iterate) against the
general path it replaced (the iterate written into (nc, 2) arrays, then
compute.contact.residual.local_contact_error), one thread, on random data of a 1500-disk
high-pressure problem's size: half the contacts at r_n = 0, so the general path's cone branches
mispredict often (real problems' active sets change little between iterations, which favours the
general path). Both return the same number; each figure is the least of five loops of 200 calls.

    python benchmarks/stop_test_cost.py [--contacts 26654]

Prints a Markdown table (ms per call); quoted in benchmarks/results/mprgp_product.md.
"""

from __future__ import annotations

import argparse
import time

import numba
import numpy as np

from compute.contact.residual import KINDS, local_contact_error
from compute.solvers.mprgp import _error


@numba.njit(cache=True)
def general_path(kind, tol, bound, wnn, s, y, g, q, u, w, r, mu, size):
    """The iterate's error through the per-contact arrays of local_contact_error."""
    for c in range(y.size):
        un = g[c] / s[c]
        r[c, 0] = s[c] * y[c]
        u[c, 0] = un
        w[c, 0] = un - q[c, 0]
        size[c] = abs(q[c, 0]) + abs(un) + abs(q[c, 1])
    return local_contact_error(kind, tol, bound, wnn, u, w, r, mu, size)


def best_ms(call) -> float:
    """The least time of five loops of 200 calls, in ms per call."""
    call()
    best = np.inf
    for _ in range(5):
        t = time.perf_counter()
        for _ in range(200):
            call()
        best = min(best, (time.perf_counter() - t) / 200)
    return 1e3 * best


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--contacts", type=int, default=26654)
    nc = p.parse_args().contacts
    rng = np.random.default_rng(1)
    wnn = rng.uniform(0.1, 10.0, nc)
    s, rho = 1.0 / np.sqrt(wnn), 1.0 / wnn
    y, g, q = np.maximum(rng.normal(size=nc), 0.0), rng.normal(size=nc), rng.normal(size=(nc, 2))
    u, w, r, size, mu = np.zeros((nc, 2)), np.zeros((nc, 2)), np.zeros((nc, 2)), np.empty(nc), np.zeros(nc)
    print(f"| measure ({nc} contacts) | general path ms | one pass ms |\n|---|---|---|")
    for name in ("impulse", "velocity"):
        kind = KINDS[name]
        before = lambda: general_path(kind, 1e-4, 0.0, wnn, s, y, g, q, u, w, r, mu, size)  # noqa: E731
        after = lambda: _error(kind, 1e-4, 0.0, wnn, rho, s, y, g, q)  # noqa: E731
        assert before() == after()
        print(f"| {name} | {best_ms(before):.3f} | {best_ms(after):.3f} |")


if __name__ == "__main__":
    numba.set_num_threads(1)
    main()
