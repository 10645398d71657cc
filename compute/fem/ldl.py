r"""Batched sparse LDL^T for many bodies sharing one symmetric sparsity pattern.

All the disks of a scene are one reference mesh, so their Newton matrices M + h^2 theta^2 K_t
(n = 2 n_nodes, dofs [x0, y0, x1, y1, ...]) share one pattern. ``SymbolicLDL`` computes the
ordering and the pattern of L once per pattern; its numba kernels then factorise, solve and form
compliance blocks for all the bodies at once, in parallel over bodies (each body serially).

Algorithm (after Davis' LDL package, ACM TOMS 2005; Liu's row-subtree characterisation):

- Ordering P (new index -> old ``perm``): the candidates below are computed and the one with the
  fewest flops kept (``candidates`` maps name -> (nnz_l, flops)).
- Symbolic: elimination tree of P A P^T, then the pattern of row k of L = the nodes met when
  climbing the etree from every i < k with A(i, k) != 0 (the row subtree of k). Stored by
  columns (lp, li) and by rows (rptr, rcol, rpos: column and position in li of L(k, j)).
- Numeric (up-looking): row k of L solves L_{0:k,0:k} D y = A_{0:k,k} sparsely: scatter column k
  of the upper triangle into y, then for j in the row pattern ascending (a topological order:
  the etree parent of j is > j), l_kj = y_j / d_j, y -= y_j L_{:,j} (rows already computed),
  d_k = a_kk - sum_j l_kj y_j. No pivoting: the signs of d give the inertia (Sylvester) as long
  as no pivot is zero.
- Compliance: E^T A^-1 E = Y^T D^-1 Y, Y = L^-1 P E. A unit vector at new index s has L^-1 e_s
  nonzero only on the etree path from s to its root, and two such paths share a common suffix,
  so each entry is a short dot product on that suffix (faster than m full
  solves: benchmarks/results/design_figures.md).

The orderings kept (mmd for T3, mmd on the node graph for T6) are the ones with the least fill
and fewest flops on the real patterns (benchmarks/results/design_figures.md).
"""

from __future__ import annotations

import numba
import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import reverse_cuthill_mckee
from scipy.sparse.linalg import splu

__all__ = ["SymbolicLDL", "block_offsets"]


@numba.njit(cache=True)
def _symbolic(n, cptr, crow):
    """Elimination tree and pattern of L by row-subtree traversal.

    cptr (n + 1,), crow: rows i <= k of each column k of the permuted matrix. Returns parent
    (n,) (-1 at roots); lp (n + 1,), li (nnz_l,): strict lower triangle of L by columns (rows
    ascending); rptr (n + 1,), rcol (nnz_l,), rpos (nnz_l,): the same entries by rows, column j
    of L(k, j) ascending and its position in li."""
    parent = np.full(n, -1, np.int64)
    flag = np.full(n, -1, np.int64)
    colcount = np.zeros(n, np.int64)
    rptr = np.zeros(n + 1, np.int64)
    for k in range(n):  # pass 1: etree, column and row counts
        flag[k] = k
        for q in range(cptr[k], cptr[k + 1]):
            i = crow[q]
            while flag[i] != k:  # climb from i until a node already in row k's subtree
                if parent[i] == -1:
                    parent[i] = k
                colcount[i] += 1
                rptr[k + 1] += 1
                flag[i] = k
                i = parent[i]
    rptr = np.cumsum(rptr)
    lp = np.zeros(n + 1, np.int64)
    lp[1:] = np.cumsum(colcount)
    li = np.empty(lp[n], np.int64)
    rcol, rpos = np.empty(lp[n], np.int64), np.empty(lp[n], np.int64)
    fill = lp[:n].copy()
    flag[:] = -1
    for k in range(n):  # pass 2: the same climb, recording row k, placed in its columns
        flag[k] = k
        top = rptr[k]
        for q in range(cptr[k], cptr[k + 1]):
            i = crow[q]
            while flag[i] != k:
                rcol[top] = i
                top += 1
                flag[i] = k
                i = parent[i]
        rcol[rptr[k]:top] = np.sort(rcol[rptr[k]:top])
        for q in range(rptr[k], top):
            j = rcol[q]
            rpos[q] = fill[j]
            li[fill[j]] = k
            fill[j] += 1
    return parent, lp, li, rptr, rcol, rpos


@numba.njit(cache=True, parallel=True)
def _factorize(data, bodies, cptr, crow, csrc, lp, li, rptr, rcol, rpos, lx, d, neg):
    """Up-looking LDL^T of every body in bodies (k,): data (B, nnz) -> lx (B, nnz_l), d (B, n);
    neg[b] = number of negative pivots, -1 at a zero or non-finite pivot (factorisation
    stopped there). cptr, crow, csrc: upper triangle of P A P^T by columns, with the positions
    of its values in the input data."""
    n = d.shape[1]
    for t in numba.prange(bodies.size):
        b = bodies[t]
        ab, lxb, db = data[b], lx[b], d[b]
        y = np.zeros(n)
        count = 0
        for k in range(n):
            for q in range(cptr[k], cptr[k + 1]):  # y = A(0:k, k)
                y[crow[q]] += ab[csrc[q]]
            dk = y[k]
            y[k] = 0.0
            for q in range(rptr[k], rptr[k + 1]):  # sparse triangular solve for row k of L
                j, pos = rcol[q], rpos[q]
                yj = y[j]
                y[j] = 0.0
                for p in range(lp[j], pos):
                    y[li[p]] -= lxb[p] * yj
                lkj = yj / db[j]
                dk -= lkj * yj
                lxb[pos] = lkj
            if dk == 0.0 or not np.isfinite(dk):
                count = -1
                break
            db[k] = dk
            if dk < 0.0:
                count += 1
        neg[b] = count


@numba.njit(cache=True, parallel=True)
def _solve(lx, d, rhs, bodies, perm, lp, li, out):
    """out[b] = A_b^-1 rhs[b] for b in bodies: P^T L^-T D^-1 L^-1 P rhs[b]; rhs, out (B, n)."""
    n = d.shape[1]
    for t in numba.prange(bodies.size):
        b = bodies[t]
        lxb, db = lx[b], d[b]
        y = np.empty(n)
        for k in range(n):
            y[k] = rhs[b, perm[k]]
        for j in range(n):  # forward: L z = P rhs
            yj = y[j]
            for p in range(lp[j], lp[j + 1]):
                y[li[p]] -= lxb[p] * yj
        for j in range(n - 1, -1, -1):  # diagonal and backward: L^T w = D^-1 z
            s = y[j] / db[j]
            for p in range(lp[j], lp[j + 1]):
                s -= lxb[p] * y[li[p]]
            y[j] = s
        for k in range(n):
            out[b, perm[k]] = y[k]


@numba.njit(cache=True, parallel=True)
def _compliance(lx, d, start, dofs, offsets, bodies, pinv, parent, lp, li, height, values):
    """Blocks E_b^T A_b^-1 E_b (row-major at values[offsets[b]:]) for b in bodies, E_b the unit
    columns of dofs[start[b]:start[b + 1]] (original numbering); height: longest etree path."""
    n = d.shape[1]
    for t in numba.prange(bodies.size):
        b = bodies[t]
        lxb, db = lx[b], d[b]
        m = start[b + 1] - start[b]
        path = np.empty((m, height), np.int64)  # etree path of each unit vector ...
        y = np.empty((m, height))  # ... and L^-1 P e on it
        yd = np.empty((m, height))  # D^-1 L^-1 P e
        length = np.empty(m, np.int64)
        w = np.zeros(n)
        for a in range(m):  # sparse forward substitution from the unit vector, up the etree
            j = pinv[dofs[start[b] + a]]
            w[j] = 1.0
            c = 0
            while j != -1:
                wj = w[j]
                w[j] = 0.0
                for p in range(lp[j], lp[j + 1]):
                    w[li[p]] -= lxb[p] * wj
                path[a, c], y[a, c], yd[a, c] = j, wj, wj / db[j]
                c += 1
                j = parent[j]
            length[a] = c
        o = offsets[b]
        for a in range(m):  # weighted Gram product on the common suffix of the two paths
            for e in range(a, m):
                s = 0.0
                ia, ie = length[a] - 1, length[e] - 1
                while ia >= 0 and ie >= 0 and path[a, ia] == path[e, ie]:
                    s += yd[a, ia] * y[e, ie]
                    ia -= 1
                    ie -= 1
                values[o + a * m + e] = s
                values[o + e * m + a] = s


def block_offsets(start: np.ndarray) -> np.ndarray:
    """Offsets (B + 1,) of the row-major blocks m_b x m_b, m_b = start[b + 1] - start[b]."""
    m = np.diff(np.asarray(start, dtype=np.int64))
    return np.concatenate([[0], np.cumsum(m * m)]).astype(np.int64)


def _mmd(pattern: sp.csr_matrix) -> np.ndarray:
    """SuperLU's minimum degree ordering of pattern + pattern^T (new -> old)."""
    n = pattern.shape[0]
    a = sp.csc_matrix((np.ones(pattern.nnz), pattern.indices, pattern.indptr), shape=(n, n))
    lu = splu(a + n * sp.identity(n, format="csc"), permc_spec="MMD_AT_PLUS_A",
              diag_pivot_thresh=0.0, options=dict(SymmetricMode=True))
    return np.argsort(lu.perm_c)  # perm_c: old -> new


def _orderings(pattern: sp.csr_matrix) -> dict[str, np.ndarray]:
    """Candidate fill-reducing orderings (new -> old) of a symmetric pattern (n, n)."""
    n = pattern.shape[0]
    out = {"natural": np.arange(n), "mmd": _mmd(pattern),
           "rcm": reverse_cuthill_mckee(pattern, symmetric_mode=True)}
    if n % 2 == 0:  # node graph: the quotient by the dof pairs (2a, 2a + 1)
        q = sp.csr_matrix((np.ones(n), (np.arange(n) // 2, np.arange(n))))
        nodes = (q @ pattern @ q.T).tocsr()
        for name, order in (("mmd", _mmd(nodes)),
                            ("rcm", reverse_cuthill_mckee(nodes, symmetric_mode=True))):
            out[name + "_nodes"] = (2 * order[:, None] + np.arange(2)).ravel()
    return {k: np.asarray(v, dtype=np.int64) for k, v in out.items()}


def _bodies(active: np.ndarray, n_bodies: int) -> np.ndarray:
    """Indices (k,) of the active bodies, active (B,) bool."""
    active = np.asarray(active, dtype=np.bool_)
    if active.shape != (n_bodies,):
        raise ValueError(f"active must have shape ({n_bodies},), got {active.shape}")
    return np.flatnonzero(active).astype(np.int64)


def _check(name: str, a: np.ndarray, shape: tuple) -> None:
    """A float64 array of the given shape (the kernels write into it in place), or ValueError."""
    if a.shape != shape or a.dtype != np.float64:
        raise ValueError(f"{name} must be float64 of shape {shape}, got {a.dtype} {a.shape}")


class SymbolicLDL:
    """Ordering and pattern of L for one symmetric sparsity pattern, computed once (no values).

    Built from the CSR pattern of a symmetric n x n matrix (both triangles and the diagonal
    present): indptr (n + 1,), indices (nnz,). Attributes: n, nnz (of the input pattern), perm
    (n,) the fill-reducing ordering (new index -> old index), nnz_l (entries of the strict lower
    triangle of L), ordering (name of the kept candidate), flops (of one numeric factorisation),
    candidates {name: (nnz_l, flops)}. The values of A are read from its upper triangle in the
    new numbering (A is assumed symmetric).
    """

    def __init__(self, indptr: np.ndarray, indices: np.ndarray) -> None:
        indptr = np.asarray(indptr, dtype=np.int64)
        indices = np.asarray(indices, dtype=np.int64)
        n = indptr.size - 1
        pattern = sp.csr_matrix((np.ones(indices.size), indices, indptr), shape=(n, n))
        if (pattern != pattern.T).nnz or (pattern.diagonal() == 0).any():
            raise ValueError("the pattern must be symmetric with its whole diagonal")
        self.n, self.nnz = n, indices.size
        rows = np.repeat(np.arange(n), np.diff(indptr))
        best = None
        self.candidates = {}
        for name, perm in _orderings(pattern).items():
            pinv = np.empty(n, np.int64)
            pinv[perm] = np.arange(n)
            col, row = pinv[rows], pinv[indices]  # entry (row, col) of P A P^T, upper if row <= col
            src = np.flatnonzero(row <= col)
            src = src[np.lexsort((row[src], col[src]))]
            cptr = np.searchsorted(col[src], np.arange(n + 1)).astype(np.int64)
            sym = _symbolic(n, cptr, row[src])
            c = np.diff(sym[1])
            flops = int((c * (c + 2)).sum())
            self.candidates[name] = (int(sym[1][n]), flops)
            if best is None or flops < best[0]:
                best = (flops, name, perm, pinv, cptr, row[src], src, sym)
        self.flops, self.ordering, self.perm, self._pinv, *arrays, sym = best
        self._cptr, self._crow, self._csrc = arrays
        self._parent, self._lp, self._li, self._rptr, self._rcol, self._rpos = sym
        self.nnz_l = int(self._lp[n])
        depth = np.ones(n, np.int64)  # nodes on the etree path from j to its root
        for j in range(n - 1, -1, -1):
            if self._parent[j] >= 0:
                depth[j] = depth[self._parent[j]] + 1
        self._height = int(depth.max(initial=0))

    def factorize(self, data: np.ndarray, active: np.ndarray, lx: np.ndarray,
                  d: np.ndarray) -> np.ndarray:
        """Numeric LDL^T of P A_b P^T = L_b D_b L_b^T for every body b with active[b]; A_b has
        values data[b] (B, nnz) in the input CSR pattern. Writes lx[b] (B, nnz_l) and d[b]
        (B, n) of active bodies only (others untouched). Returns (B,) int64: the number of
        negative pivots of each active body, -1 if a pivot was zero or not finite (factorisation
        unusable), 0 for inactive bodies. Parallel over active bodies."""
        data = np.ascontiguousarray(data, dtype=np.float64)
        n_bodies = data.shape[0]
        _check("data", data, (n_bodies, self.nnz))
        _check("lx", lx, (n_bodies, self.nnz_l))
        _check("d", d, (n_bodies, self.n))
        neg = np.zeros(n_bodies, np.int64)
        _factorize(data, _bodies(active, n_bodies), self._cptr, self._crow, self._csrc, self._lp,
                   self._li, self._rptr, self._rcol, self._rpos, lx, d, neg)
        return neg

    def solve(self, lx: np.ndarray, d: np.ndarray, rhs: np.ndarray, active: np.ndarray,
              out: np.ndarray) -> None:
        """out[b] = A_b^-1 rhs[b] (rhs, out: (B, n); out may be rhs) for every active body, from
        its factors lx (B, nnz_l), d (B, n)."""
        rhs = np.ascontiguousarray(rhs, dtype=np.float64)
        n_bodies = d.shape[0]
        for name, a, shape in (("lx", lx, (n_bodies, self.nnz_l)), ("d", d, (n_bodies, self.n)),
                               ("rhs", rhs, d.shape), ("out", out, d.shape)):
            _check(name, a, shape)
        _solve(lx, d, rhs, _bodies(active, n_bodies), self.perm, self._lp, self._li, out)

    def compliance(self, lx: np.ndarray, d: np.ndarray, start: np.ndarray, dofs: np.ndarray,
                   active: np.ndarray, values: np.ndarray) -> None:
        """Dense blocks C_b = E_b^T A_b^-1 E_b for the unit columns E_b of the dofs
        dofs[start[b]:start[b + 1]] (start (B + 1,), dofs (sum m_b,), original numbering), from
        the factors lx (B, nnz_l), d (B, n). Block b, row-major (m_b, m_b), goes to
        values[o_b : o_b + m_b**2], o_b = block_offsets(start)[b]; only active bodies are
        written; the blocks are exactly symmetric."""
        n_bodies = d.shape[0]
        start = np.asarray(start, dtype=np.int64)
        dofs = np.asarray(dofs, dtype=np.int64)
        offsets = block_offsets(start)
        _check("lx", lx, (n_bodies, self.nnz_l))
        _check("d", d, (n_bodies, self.n))
        _check("values", values, (offsets[-1],))
        if (start.shape != (n_bodies + 1,) or start[0] != 0 or (np.diff(start) < 0).any()
                or dofs.shape != (start[-1],)):
            raise ValueError(f"start must be nondecreasing from 0, shape ({n_bodies + 1},); "
                             "dofs of shape (start[-1],)")
        if dofs.size and (dofs.min() < 0 or dofs.max() >= self.n):
            raise ValueError(f"dofs must lie in 0..{self.n - 1}")
        _compliance(lx, d, start, dofs, offsets, _bodies(active, n_bodies), self._pinv,
                    self._parent, self._lp, self._li, self._height, values)
