r"""MPRGP's preconditioner in face: the block diagonal of the scaled normal Delassus operator by
soft body, restricted to the free contacts.

In a pressed soft packing W_nn = H_nᵀ M̂⁻¹ H_n is ill-conditioned mostly within the rows of one
body: the rows of an interface held both ways (each disk's nodes on the other's segments) are
nearly dependent, and the rows around a nearly incompressible disk see its volume change as
almost rigid and its shear as soft. Conjugate gradients on the unit-diagonal A = S W_nn S then
spend their iterations on modes a body's own rows hold, which a solve with that body's block
removes (figures: benchmarks/results/mprgp_preconditioner.md).

Groups: each contact row joins the soft body of lowest index among those its dofs belong to (so
both directions of an interface fall in one group); rows that touch no soft body stand alone,
with the identity (their diagonal of A is 1). Block B_G = A[G, G], computed exactly from the
packed rows and the compliance.

In face (Dostál, Optimal Quadratic Programming Algorithms, 2009, §5.10): for the free set
F = {y > 0}, z = M_F⁻¹ g with M_F the block diagonal of B_G[F_G, F_G], z = 0 off F. A group's
free block is factorised by Cholesky when its free rows change, and kept otherwise. A pivot
below ``PIVOT`` (rows dependent within rounding) is set to 1, which leaves that direction
unpreconditioned and M_F positive definite.
"""

from __future__ import annotations

import numba
import numpy as np

PIVOT = 1e-12  # of a unit-diagonal block: below it a row is taken as dependent on the others


@numba.njit(cache=True)
def row_groups(dof, block):
    """(ptr (ng + 1,), rows): group G holds the contacts rows[ptr[G]:ptr[G + 1]] (increasing), the
    rows whose lowest soft block (``block`` of their packed dofs ``dof`` (nc, m), -1 for a 1x1
    dof) is the same; only groups of two rows or more."""
    nc, m = dof.shape
    nb = 0
    for d in range(block.size):
        nb = max(nb, block[d] + 1)
    key = np.full(nc, -1, np.int64)
    count = np.zeros(nb + 1, np.int64)
    for c in range(nc):
        for a in range(m):
            d = dof[c, a]
            if d >= 0 and block[d] >= 0 and (key[c] < 0 or block[d] < key[c]):
                key[c] = block[d]
        if key[c] >= 0:
            count[key[c]] += 1
    where = np.full(nb, -1, np.int64)  # group of each block
    ng = 0
    for b in range(nb):
        if count[b] >= 2:
            where[b] = ng
            ng += 1
    ptr = np.zeros(ng + 1, np.int64)
    for b in range(nb):
        if where[b] >= 0:
            ptr[where[b] + 1] = count[b]
    for g in range(ng):
        ptr[g + 1] += ptr[g]
    rows = np.empty(ptr[ng], np.int64)
    fill = ptr[:-1].copy()
    for c in range(nc):
        if key[c] >= 0 and where[key[c]] >= 0:
            g = where[key[c]]
            rows[fill[g]] = c
            fill[g] += 1
    return ptr, rows


@numba.njit(cache=True)
def group_blocks(ptr, rows, s, dof, hn, diagonal, block, start, offset, values):
    """(boff (ng + 1,), bval): B_G = S W_nn S on the rows of group G, k_G × k_G row-major at
    bval[boff[G]:boff[G + 1]]; ``s`` (nc,) the scaling, ``dof``, ``hn`` the packed normal rows,
    the rest the compliance arrays. Column j of B_G is H_iᵀ (M̂⁻¹ H_j) over the group's rows i,
    M̂⁻¹ H_j made once in a dense work vector (a compliance column per soft dof of row j)."""
    ng = ptr.size - 1
    m = dof.shape[1]
    boff = np.zeros(ng + 1, np.int64)
    for g in range(ng):
        k = ptr[g + 1] - ptr[g]
        boff[g + 1] = boff[g] + k * k
    bval = np.empty(boff[ng])
    v = np.zeros(diagonal.size)
    for g in range(ng):
        k = ptr[g + 1] - ptr[g]
        o = boff[g]
        for j in range(k):
            cj = rows[ptr[g] + j]
            for a in range(m):  # v = M̂⁻¹ H_j
                d = dof[cj, a]
                if d < 0:
                    continue
                b = block[d]
                if b < 0:
                    v[d] += diagonal[d] * hn[cj, a]
                else:
                    s0 = start[b]
                    n = start[b + 1] - s0
                    col = offset[b] + d - s0
                    for i in range(n):
                        v[s0 + i] += values[col + i * n] * hn[cj, a]
            for i in range(k):
                ci = rows[ptr[g] + i]
                x = 0.0
                for a in range(m):
                    d = dof[ci, a]
                    if d >= 0:
                        x += hn[ci, a] * v[d]
                bval[o + i * k + j] = s[ci] * x * s[cj]
            for a in range(m):  # v = 0 again
                d = dof[cj, a]
                if d < 0:
                    continue
                b = block[d]
                if b < 0:
                    v[d] = 0.0
                else:
                    v[start[b]:start[b + 1]] = 0.0
    return boff, bval


@numba.njit(cache=True)
def preconditioner(ptr, rows, s, dof, hn, diagonal, block, start, offset, values):
    """The preconditioner's arrays (ptr, rows, boff, bval, factors, free, local, factored) for
    :func:`apply`: the groups and blocks (:func:`row_groups`, :func:`group_blocks`), room for a
    Cholesky factor per block, each row's free flag at its group's last factorisation, the
    free rows' local positions, and whether each group is factorised."""
    boff, bval = group_blocks(ptr, rows, s, dof, hn, diagonal, block, start, offset, values)
    ng = ptr.size - 1
    return (ptr, rows, boff, bval, np.empty(bval.size), np.zeros(rows.size, np.bool_),
            np.empty(rows.size, np.int64), np.zeros(ng, np.bool_))


@numba.njit(cache=True)
def _factor(b, k, local, nf, out):
    """Cholesky factor L (lower, row-major nf × nf in ``out``) of the rows and columns
    ``local[:nf]`` of the k × k block ``b``. A pivot below PIVOT (a row dependent on the ones
    before it) becomes 1 and its column below 0: L keeps a positive diagonal, so L Lᵀ stays
    positive definite."""
    dropped = np.zeros(nf, np.bool_)
    for i in range(nf):
        for j in range(i + 1):
            if j < i and dropped[j]:
                out[i * nf + j] = 0.0
                continue
            x = b[local[i] * k + local[j]]
            for p in range(j):
                x -= out[i * nf + p] * out[j * nf + p]
            if j < i:
                out[i * nf + j] = x / out[j * nf + j]
            elif x > PIVOT:
                out[i * nf + i] = np.sqrt(x)
            else:
                out[i * nf + i] = 1.0
                dropped[i] = True
        for j in range(i + 1, nf):
            out[i * nf + j] = 0.0


@numba.njit(cache=True)
def apply(pre, y, g, z):
    """z = M_F⁻¹ g on F = {y > 0}, 0 elsewhere (module docstring), for ``pre`` from
    :func:`preconditioner`; refactorises the groups whose free rows changed. y, g, z (nc,)."""
    ptr, rows, boff, bval, fval, free, local, factored = pre
    for c in range(y.size):
        z[c] = g[c] if y[c] > 0.0 else 0.0
    for grp in range(ptr.size - 1):
        p0 = ptr[grp]
        k = ptr[grp + 1] - p0
        changed = not factored[grp]
        nf = 0
        for i in range(k):
            f = y[rows[p0 + i]] > 0.0
            if f != free[p0 + i]:
                changed = True
                free[p0 + i] = f
            if f:
                nf += 1
        if nf < 2:
            factored[grp] = True
            continue
        o = boff[grp]
        L = fval[o:o + nf * nf]
        if changed:
            n = 0
            for i in range(k):
                if free[p0 + i]:
                    local[p0 + n] = i
                    n += 1
            _factor(bval[o:o + k * k], k, local[p0:p0 + nf], nf, L)
            factored[grp] = True
        t = np.empty(nf)
        for i in range(nf):  # L t = g_F
            x = g[rows[p0 + local[p0 + i]]]
            for p in range(i):
                x -= L[i * nf + p] * t[p]
            t[i] = x / L[i * nf + i]
        for i in range(nf - 1, -1, -1):  # Lᵀ z_F = t
            x = t[i]
            for p in range(i + 1, nf):
                x -= L[p * nf + i] * t[p]
            t[i] = x / L[i * nf + i]
        for i in range(nf):
            z[rows[p0 + local[p0 + i]]] = t[i]


@numba.njit(cache=True)
def no_preconditioner():
    """The arrays of :func:`preconditioner` with no group: MPRGP unpreconditioned."""
    return (np.zeros(1, np.int64), np.empty(0, np.int64), np.zeros(1, np.int64), np.empty(0), np.empty(0),
            np.zeros(0, np.bool_), np.empty(0, np.int64), np.zeros(0, np.bool_))
