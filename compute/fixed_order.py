"""Sums that round alike on every processor, for the kernels whose results steer a run.

A run amplifies the last bits of its arithmetic (a jamming ends on another packing, a Newton
loop takes another iteration), so the same scene must give the same bits on every machine. The
BLAS and LAPACK that numpy and scipy load (OpenBLAS) choose their kernels for the processor at
run time, and those sum in different orders (SSE3, AVX2, AVX-512: other unrolling, other partial
sums, fused multiply-adds or not): a dot product, a least-squares solve or a 2x2 inverse through
them differs in its last bits from one machine to the next
(benchmarks/results/machine_determinism.md). numba contracts no a·b + c into a fused
multiply-add unless asked, and does not reorder a sum, so a loop written here rounds alike on
every processor.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["dot", "least_squares", "matvec"]


@numba.njit(cache=True)
def dot(x, y):
    """xᵀy for x, y (n,), summed in one fixed order: four interleaved partial sums (which keeps it
    within about twice a BLAS ddot on long vectors), then their pairs."""
    n = x.size
    m = n - n % 4
    a0 = a1 = a2 = a3 = 0.0
    for i in range(0, m, 4):
        a0 += x[i] * y[i]
        a1 += x[i + 1] * y[i + 1]
        a2 += x[i + 2] * y[i + 2]
        a3 += x[i + 3] * y[i + 3]
    for i in range(m, n):
        a0 += x[i] * y[i]
    return (a0 + a1) + (a2 + a3)


@numba.njit(cache=True)
def matvec(a, x):
    """a x (m,) for a (m, n) and x (n,), each entry a :func:`dot` of a row."""
    out = np.empty(a.shape[0])
    for i in range(a.shape[0]):
        out[i] = dot(a[i], x)
    return out


@numba.njit(cache=True)
def least_squares(a, b, rcond):
    """c (m,) minimising |Σ_j c_j a_j − b| over the rows a_j of ``a`` (m, n), m small, ``b`` (n,):
    modified Gram–Schmidt, each column orthogonalised twice, a column whose remainder is at most
    ``rcond`` times the largest column's norm left out (its c_j = 0), then back substitution."""
    m, n = a.shape
    q = np.empty((m, n))
    r = np.zeros((m, m))
    kept = np.zeros(m, np.bool_)
    largest = 0.0
    for j in range(m):
        largest = max(largest, np.sqrt(dot(a[j], a[j])))
    for j in range(m):
        v = a[j].copy()
        for _ in range(2):
            for i in range(j):
                if kept[i]:
                    s = dot(q[i], v)
                    r[i, j] += s
                    for k in range(n):
                        v[k] -= s * q[i, k]
        size = np.sqrt(dot(v, v))
        if size > rcond * largest and size > 0.0:
            kept[j] = True
            r[j, j] = size
            for k in range(n):
                q[j, k] = v[k] / size
    c = np.zeros(m)
    z = np.zeros(m)
    for j in range(m):
        if kept[j]:
            z[j] = dot(q[j], b)
    for j in range(m - 1, -1, -1):
        if kept[j]:
            s = z[j]
            for i in range(j + 1, m):
                if kept[i]:
                    s -= r[j, i] * c[i]
            c[j] = s / r[j, j]
    return c
