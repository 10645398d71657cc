"""The test oracle: a textbook Lemke complementary pivoting solver (dense tableau) and the 2D
frictional contact problem written as a linear complementarity problem.

In 2D the Coulomb cone is polyhedral (two edges), so the Signorini–Coulomb problem
u = W r + b is exactly the LCP w = A z + q, 0 <= z ⊥ w >= 0 with, per contact, z = (r_n, β⁺, β⁻, λ),
r_t = β⁺ - β⁻ and

    w_n  = ũ_n                      (Signorini)
    w⁺   = λ + u_t,   w⁻ = λ - u_t  (λ ≥ |u_t|, the slip speed where r_t is on the cone's edge)
    w_λ  = μ r_n - β⁺ - β⁻          (|r_t| ≤ μ r_n, with slip only on the edge)

(Stewart & Trinkle 1996; Anitescu & Potra 1997 show Lemke's method solves it.)
"""

from __future__ import annotations

import numpy as np


def lemke(A: np.ndarray, q: np.ndarray, max_pivots: int = 10_000) -> np.ndarray:
    """z >= 0 with w = A z + q >= 0 and z·w = 0 (n,), by Lemke's method with covering vector 1;
    raises RuntimeError on ray termination or too many pivots."""
    n = len(q)
    if np.all(q >= 0.0):
        return np.zeros(n)
    tab = np.hstack([np.eye(n), -A, -np.ones((n, 1))])  # w - A z - z0 1 = q
    rhs = q.astype(float).copy()
    basis = list(range(n))  # variables: w 0..n-1, z n..2n-1, z0 2n
    z0 = 2 * n

    def do_pivot(row, col):
        p = tab[row, col]
        tab[row] /= p
        rhs[row] /= p
        for i in range(n):
            if i != row and tab[i, col] != 0.0:
                f = tab[i, col]
                tab[i] -= f * tab[row]
                rhs[i] -= f * rhs[row]
        leaving = basis[row]
        basis[row] = col
        return leaving

    leaving = do_pivot(int(np.argmin(rhs)), z0)
    for _ in range(max_pivots):
        entering = leaving + n if leaving < n else leaving - n
        col = tab[:, entering]
        ok = col > 1e-12
        if not ok.any():
            raise RuntimeError("Lemke: ray termination")
        row = _lexicographic_row(tab, rhs, col, ok, n, basis, z0)
        leaving = do_pivot(row, entering)
        if leaving == z0:
            z = np.zeros(2 * n + 1)
            z[basis] = rhs
            z = z[n:2 * n]
            return np.where(z > 1e-14 * max(1.0, np.abs(z).max()), z, 0.0)  # rounding below zero or near it
    raise RuntimeError("Lemke: too many pivots")


def _lexicographic_row(tab, rhs, col, ok, n, basis, z0) -> int:
    """The leaving row of the minimum ratio test, ties broken in favour of z0, then by the
    lexicographic rule on the rows of B⁻¹ (the tableau's w columns), which prevents cycling in
    degenerate problems (frictionless contacts make some right-hand sides zero)."""
    rows = np.flatnonzero(ok)
    ratios = rhs[rows] / col[rows]
    best = ratios.min()
    ties = rows[ratios <= best + 1e-12 * max(1.0, abs(best))]
    if any(basis[i] == z0 for i in ties):
        return next(int(i) for i in ties if basis[i] == z0)
    keys = tab[ties, :n] / col[ties, None]
    for j in range(n):
        if len(ties) == 1:
            break
        m = keys[:, j].min()
        keep = keys[:, j] <= m + 1e-12 * max(1.0, abs(m))
        ties, keys = ties[keep], keys[keep]
    return int(ties[0])


def frictional_lcp(W: np.ndarray, b: np.ndarray, mu: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(A (4 nc, 4 nc), q (4 nc,)) of the contact problem u = W r + b (W (2 nc, 2 nc) with rows
    and columns ordered n0, t0, n1, t1, ...; b (2 nc,)), unknowns z = (r_n, β⁺, β⁻, λ)."""
    nc = len(mu)
    Wnn, Wnt, Wtn, Wtt = W[0::2, 0::2], W[0::2, 1::2], W[1::2, 0::2], W[1::2, 1::2]
    I, Z = np.eye(nc), np.zeros((nc, nc))
    A = np.block([[Wnn, Wnt, -Wnt, Z],
                  [Wtn, Wtt, -Wtt, I],
                  [-Wtn, -Wtt, Wtt, I],
                  [np.diag(mu), -I, -I, Z]])
    q = np.concatenate([b[0::2], b[1::2], -b[1::2], np.zeros(nc)])
    return A, q


def solve_contact(W: np.ndarray, b: np.ndarray, mu: np.ndarray) -> np.ndarray:
    """Impulses r (nc, 2) of the contact problem u = W r + b (see frictional_lcp)."""
    nc = len(mu)
    z = lemke(*frictional_lcp(W, b, mu))
    return np.column_stack([z[:nc], z[nc:2 * nc] - z[2 * nc:3 * nc]])
