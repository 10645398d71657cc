r"""The Delassus operator of the whole packing, W = Hᵀ M̂⁻¹ H, as a sparse matrix of 2x2 blocks.

Block (c, d) is H_cᵀ M̂⁻¹ H_d (rows n, t of contact c against columns n, t of contact d): it is
non-zero only when contacts c and d touch one compliance block of
:class:`compute.contact.compliance.Compliance` (a rigid dof, or one soft body's dense block).
So W is assembled group by group: for a group G of the compliance with the k contacts that touch
it, the dense product W_G = H_Gᵀ C_G H_G ((2k, 2k), H_G the rows of those contacts restricted to
G's dofs) is added to the k² blocks of its contacts. A soft body touched by k contacts costs one
(s, s) by (s, 2k) product and (2k)² entries, never a pass over pairs of its dofs.

Stored as block-CSR over contacts: ``indptr`` (nc + 1,), ``indices`` (nnzb,) sorted within a
row, ``data`` (nnzb, 2, 2); every diagonal block (c, c) is present (zero for a contact between
two immovable bodies). The pattern is symmetric and W[d, c] = W[c, d]ᵀ.

:func:`normal_groups` keeps the normal part of the soft bodies' groups only, as one dense block
per body and without merging them: what a solver that applies the rigid dofs' part through the
compliance itself needs (compute.solvers.mprgp), at a fraction of the assembly's cost.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np


@dataclass(frozen=True)
class Delassus:
    """W in block-CSR (module docstring): ``indptr`` (nc + 1,), ``indices`` (nnzb,), ``data`` (nnzb, 2, 2)."""

    indptr: np.ndarray
    indices: np.ndarray
    data: np.ndarray

    @classmethod
    def of_problem(cls, problem) -> "Delassus":
        """W of a :class:`compute.contact.problem.ContactProblem` (its packed rows and compliance)."""
        c = problem.compliance
        return cls(*assemble(problem.dof, problem.hn, problem.ht, c.diagonal, c.block, c.start, c.offset, c.values))

    def __len__(self) -> int:
        return self.indptr.size - 1

    def times(self, r: np.ndarray) -> np.ndarray:
        """W r (nc, 2) for impulses r (nc, 2)."""
        return block_matvec(self.indptr, self.indices, self.data, r)

    def dense(self) -> np.ndarray:
        """W as a dense (2 nc, 2 nc) array, rows n0, t0, n1, t1, ... (for tests and small problems)."""
        nc = len(self)
        out = np.zeros((2 * nc, 2 * nc))
        for c in range(nc):
            for p in range(self.indptr[c], self.indptr[c + 1]):
                d = self.indices[p]
                out[2 * c:2 * c + 2, 2 * d:2 * d + 2] = self.data[p]
        return out


@numba.njit(cache=True)
def _groups(dof, block, n_blocks):
    """The compliance groups and the contacts touching each: (keys (g,), ptr (g + 1,), contacts):
    group q is dense block keys[q] (< n_blocks) or the 1x1 dof keys[q] - n_blocks, touched by
    contacts[ptr[q]:ptr[q + 1]] (sorted, unique). A counting sort over the groups, one pass over
    the rows to count and one to fill."""
    nc, m = dof.shape
    n_keys = n_blocks + block.size
    count = np.zeros(n_keys, np.int64)
    last = np.full(n_keys, -1, np.int64)
    first_entry = np.full((nc, m), -1, np.int64)  # the group of a row entry, where it is the row's first in it
    for c in range(nc):
        for a in range(m):
            d = dof[c, a]
            if d >= 0:
                key = block[d] if block[d] >= 0 else n_blocks + d
                if last[key] != c:
                    last[key] = c
                    count[key] += 1
                    first_entry[c, a] = key
    keys = np.flatnonzero(count)
    ptr = np.zeros(keys.size + 1, np.int64)
    fill = np.zeros(n_keys, np.int64)  # the next place of each group's contacts
    for q in range(keys.size):
        ptr[q + 1] = ptr[q] + count[keys[q]]
        fill[keys[q]] = ptr[q]
    contacts = np.empty(ptr[-1], np.int64)
    for c in range(nc):
        for a in range(m):
            key = first_entry[c, a]
            if key >= 0:
                contacts[fill[key]] = c
                fill[key] += 1
    return keys, ptr, contacts


@numba.njit(cache=True, parallel=True)
def _group_blocks(dof, hn, ht, diagonal, start, offset, values, n_blocks, keys, ptr, contacts, out_ptr,
                  rows, cols, vals):
    """W_G = H_Gᵀ C_G H_G of every group G, written as its k² 2x2 blocks from out_ptr[G]."""
    m = dof.shape[1]
    for q in numba.prange(keys.size):
        K = keys[q]
        k = ptr[q + 1] - ptr[q]
        if K < n_blocks:
            s0 = start[K]
            s = start[K + 1] - s0
            C = values[offset[K]:offset[K + 1]].reshape((s, s))
        else:
            s0 = K - n_blocks
            s = 1
            C = np.full((1, 1), diagonal[s0])
        Hg = np.zeros((s, 2 * k))
        for i in range(k):
            c = contacts[ptr[q] + i]
            for a in range(m):
                d = dof[c, a]
                if d >= s0 and d < s0 + s and (K < n_blocks or d == s0):
                    Hg[d - s0, 2 * i] += hn[c, a]
                    Hg[d - s0, 2 * i + 1] += ht[c, a]
        CH = np.zeros((s, 2 * k))  # C_G H_G and H_Gᵀ (C_G H_G), summed in a fixed order (compute.fixed_order)
        for a in range(s):
            for b in range(s):
                if C[a, b] != 0.0:
                    for j in range(2 * k):
                        CH[a, j] += C[a, b] * Hg[b, j]
        Wg = np.zeros((2 * k, 2 * k))
        for a in range(s):
            for i in range(2 * k):
                if Hg[a, i] != 0.0:
                    for j in range(2 * k):
                        Wg[i, j] += Hg[a, i] * CH[a, j]
        o = out_ptr[q]
        for i in range(k):
            for j in range(k):
                rows[o] = contacts[ptr[q] + i]
                cols[o] = contacts[ptr[q] + j]
                for x in range(2):
                    for y in range(2):
                        vals[o, x, y] = Wg[2 * i + x, 2 * j + y]
                o += 1


@numba.njit(cache=True)
def assemble(dof, hn, ht, diagonal, block, start, offset, values):
    """W = Hᵀ C H in block-CSR (module docstring) from packed rows ``dof``, ``hn``, ``ht`` (nc, m)
    and the compliance arrays: (indptr (nc + 1,), indices (nnzb,), data (nnzb, 2, 2))."""
    nc = dof.shape[0]
    n_blocks = start.size - 1
    keys, ptr, contacts = _groups(dof, block, n_blocks)
    sizes = np.diff(ptr)
    out_ptr = np.zeros(keys.size + 1, np.int64)
    for q in range(keys.size):
        out_ptr[q + 1] = out_ptr[q] + sizes[q] * sizes[q]
    total = out_ptr[-1] + nc  # plus a zero diagonal block per contact
    rows = np.empty(total, np.int64)
    cols = np.empty(total, np.int64)
    vals = np.zeros((total, 2, 2))
    _group_blocks(dof, hn, ht, diagonal, start, offset, values, n_blocks, keys, ptr, contacts, out_ptr,
                  rows, cols, vals)
    for c in range(nc):
        rows[out_ptr[-1] + c] = c
        cols[out_ptr[-1] + c] = c
    order = np.argsort(rows * max(nc, 1) + cols, kind="mergesort")
    indptr = np.zeros(nc + 1, np.int64)
    indices = np.empty(total, np.int64)
    data = np.zeros((total, 2, 2))
    nnz = -1
    last = -1
    for i in order:
        key = rows[i] * nc + cols[i]
        if key != last:
            nnz += 1
            indices[nnz] = cols[i]
            indptr[rows[i] + 1] += 1
            last = key
        data[nnz] += vals[i]
    for c in range(nc):
        indptr[c + 1] += indptr[c]
    return indptr, indices[:nnz + 1].copy(), data[:nnz + 1].copy()


@numba.njit(cache=True)
def block_matvec(indptr, indices, data, r):
    """W r (nc, 2) of a block-CSR W and impulses r (nc, 2)."""
    nc = indptr.size - 1
    u = np.zeros((nc, 2))
    for c in range(nc):
        un = 0.0
        ut = 0.0
        for p in range(indptr[c], indptr[c + 1]):
            d = indices[p]
            un += data[p, 0, 0] * r[d, 0] + data[p, 0, 1] * r[d, 1]
            ut += data[p, 1, 0] * r[d, 0] + data[p, 1, 1] * r[d, 1]
        u[c, 0] = un
        u[c, 1] = ut
    return u


@numba.njit(cache=True)
def normal_groups(dof, hn, block, start, offset, values):
    r"""The normal Delassus operator's part from the dense compliance blocks (the soft bodies), as
    the cheaper of two forms per block G with s_G dofs and the k_G contacts whose normal rows touch
    it: the dense W_G = H_G,nᵀ C_G H_G,n (k_G, k_G) where k_G < s_G (a product then costs k_G²
    instead of s_G²), the compliance block C_G itself elsewhere (contacts crowding a body's
    boundary, as soft–soft rows both ways do). W_nn = Σ_G W_G + H_nᵀ D H_n, D the 1x1 blocks and
    the blocks kept as compliance. Both forms are symmetric and kept as their upper triangles,
    packed row by row (:func:`packed_times`): a product then reads half the values, and reading
    them is most of its cost once a packing's blocks outgrow the processor's caches.

    ``dof``, ``hn`` (nc, m) packed normal rows; the compliance arrays ``block``, ``start``,
    ``offset``, ``values``. Returns (dense (n_blocks,) bool: whether block G has its W_G; ptr
    (n_blocks + 1,), contacts: the contacts of a dense block G are contacts[ptr[G]:ptr[G + 1]],
    in increasing order (none for the others); woff (n_blocks + 1,), wval: the triangle of W_G
    at wval[woff[G]:woff[G + 1]]; coff (n_blocks + 1,), cval: the triangle of C_G of a block
    without its W_G at cval[coff[G]:coff[G + 1]]). Building W_G costs one column of C_G per
    touched dof, then k_G² / 2 short dot products."""
    nc, m = dof.shape
    nb = start.size - 1
    keys, group_ptr, group_contacts = _groups(dof, block, nb)
    dense = np.zeros(nb, np.bool_)
    first = np.zeros(nb, np.int64)  # where a dense block's contacts start in group_contacts
    count = np.zeros(nb, np.int64)
    for q in range(keys.size):
        g = keys[q]
        if g < nb and group_ptr[q + 1] - group_ptr[q] < start[g + 1] - start[g]:
            dense[g] = True
            first[g] = group_ptr[q]
            count[g] = group_ptr[q + 1] - group_ptr[q]
    ptr = np.zeros(nb + 1, np.int64)
    woff = np.zeros(nb + 1, np.int64)
    coff = np.zeros(nb + 1, np.int64)
    for g in range(nb):
        ptr[g + 1] = ptr[g] + count[g]
        woff[g + 1] = woff[g] + count[g] * (count[g] + 1) // 2
        s = 0 if dense[g] else start[g + 1] - start[g]
        coff[g + 1] = coff[g] + s * (s + 1) // 2
    contacts = np.empty(ptr[nb], np.int64)
    for g in range(nb):
        contacts[ptr[g]:ptr[g + 1]] = group_contacts[first[g]:first[g] + count[g]]
    wval = np.zeros(woff[nb])
    cval = np.empty(coff[nb])
    for g in range(nb):
        s0 = start[g]
        s = start[g + 1] - s0
        if not dense[g]:
            q = coff[g]
            for i in range(s):
                for j in range(i, s):
                    cval[q] = values[offset[g] + i * s + j]
                    q += 1
            continue
        k = count[g]
        y = np.zeros((s, k))  # C_G H_G,n, column by column
        for j in range(k):
            c = contacts[ptr[g] + j]
            for a in range(m):
                d = dof[c, a]
                if d >= 0 and block[d] == g:
                    o = offset[g] + (d - s0) * s  # row d of the symmetric block: its column d
                    for i in range(s):
                        y[i, j] += hn[c, a] * values[o + i]
        row = woff[g]  # where row i of the packed triangle starts (entries j = i .. k - 1)
        for i in range(k):
            c = contacts[ptr[g] + i]
            for a in range(m):
                d = dof[c, a]
                if d >= 0 and block[d] == g:
                    for j in range(i, k):
                        wval[row + j - i] += hn[c, a] * y[d - s0, j]
            row += k - i
    return dense, ptr, contacts, woff, wval, coff, cval


@numba.njit(cache=True)
def packed_times(tri, n, x, y):
    """y += A x for the symmetric (n, n) A whose upper triangle ``tri`` (n (n + 1) / 2,) is packed
    row by row (row i's entries j = i .. n - 1 from (2n - i + 1) i / 2); ``x``, ``y`` (n,) (any
    1D views). Each value is read once and used twice: for row i's sum and for y[j] += A_ij x_i.

    Rows go four at a time: their four sums run side by side over the columns right of the 4 x 4
    diagonal block, and each y[j] is loaded and stored once for the four. Why: one row at a time,
    every value waits for the addition before it to its row's sum (a chain of dependent additions,
    the latency of one per value), which made a product latency-bound; four independent chains
    take a quarter of that (figures: benchmarks/results/mprgp_product.md). The sums' order is
    fixed by this code, not by the processor (compute.fixed_order). The last n mod 4 rows go one
    at a time."""
    i = 0
    q = 0  # where row i starts
    while i + 4 <= n:
        q0 = q
        q1 = q0 + n - i
        q2 = q1 + n - i - 1
        q3 = q2 + n - i - 2
        x0, x1, x2, x3 = x[i], x[i + 1], x[i + 2], x[i + 3]
        a01, a02, a03 = tri[q0 + 1], tri[q0 + 2], tri[q0 + 3]  # the diagonal block, (a, b) at q_a + b - a
        a12, a13, a23 = tri[q1 + 1], tri[q1 + 2], tri[q2 + 1]
        s0 = ((tri[q0] * x0 + a01 * x1) + a02 * x2) + a03 * x3
        s1 = ((a01 * x0 + tri[q1] * x1) + a12 * x2) + a13 * x3
        s2 = ((a02 * x0 + a12 * x1) + tri[q2] * x2) + a23 * x3
        s3 = ((a03 * x0 + a13 * x1) + a23 * x2) + tri[q3] * x3
        for t in range(n - i - 4):  # the columns j = i + 4 .. n - 1
            j = i + 4 + t
            u0, u1, u2, u3 = tri[q0 + 4 + t], tri[q1 + 3 + t], tri[q2 + 2 + t], tri[q3 + 1 + t]
            xj = x[j]
            s0 += u0 * xj
            s1 += u1 * xj
            s2 += u2 * xj
            s3 += u3 * xj
            y[j] += (u0 * x0 + u1 * x1) + (u2 * x2 + u3 * x3)
        y[i] += s0
        y[i + 1] += s1
        y[i + 2] += s2
        y[i + 3] += s3
        q = q3 + n - i - 3
        i += 4
    while i < n:
        xi = x[i]
        acc = tri[q] * xi
        q += 1
        for j in range(i + 1, n):
            a = tri[q]
            q += 1
            acc += a * x[j]
            y[j] += a * xi
        y[i] += acc
        i += 1
