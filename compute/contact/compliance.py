"""The inverse effective mass M̂⁻¹ seen by the contact solver, as a block-diagonal matrix in its
own packed numbering of the dofs.

Rigid-body and wall dofs are 1x1 blocks (1 / mass, 1 / inertia); a deformable body contributes
one dense block over its boundary dofs, taken from its factorised effective matrix
M̂ = M + h²θ² K_t. The contact solver only needs ``v += M̂⁻¹ H Δr`` restricted to dofs that
contacts touch, which these blocks give exactly.

Packed numbering: the contact solver works on the velocities of these dofs only, numbered dense
block after dense block, then the 1x1 ones. A dense block's dofs are then consecutive, and adding
one of its columns to v (what every impulse change of a soft body's contact costs) is a
contiguous axpy instead of a scatter through a list of dofs, on the contact updates that are
most of an NLGS sweep (benchmarks/results/packed_velocities.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np


@dataclass
class Compliance:
    """Block-diagonal M̂⁻¹ over n packed dofs (module docstring).

    ``order`` (n,) the global dof of each packed dof; ``index`` (n_dofs,) the packed dof of each
    global dof (-1: not in it); ``diagonal`` (n,) the 1x1 blocks (0 on dense blocks); ``block``
    (n,) dense block of each packed dof (-1: none); ``start`` (n_blocks + 1,): block b holds the
    packed dofs start[b] .. start[b + 1] - 1; ``offset`` (n_blocks + 1,) offsets into ``values``,
    the row-major entries of the (symmetric) blocks.
    """

    order: np.ndarray
    index: np.ndarray
    diagonal: np.ndarray
    block: np.ndarray
    start: np.ndarray
    offset: np.ndarray
    values: np.ndarray

    @classmethod
    def build(cls, n_dofs: int, diagonals=(), dense=()) -> "Compliance":
        """From 1x1 blocks ``diagonals`` = [(dofs (k,), values (k,))] and dense blocks ``dense`` =
        [(start (B + 1,), dofs (m,), values)] over global dofs 0 .. n_dofs - 1: per group, block b
        over dofs[start[b]:start[b+1]] with row-major values (concatenated, sizes
        (start[b+1] - start[b])**2); empty blocks allowed. A dof in two blocks is an error."""
        sizes = np.concatenate([np.zeros(0, np.int64)] + [np.diff(st) for st, _, _ in dense])
        block_dofs = np.concatenate([np.zeros(0, np.int64)] + [np.asarray(d, np.int64) for _, d, _ in dense])
        single = np.concatenate([np.zeros(0, np.int64)] + [np.asarray(d, np.int64) for d, _ in diagonals])
        order = np.concatenate([block_dofs, single])
        index = np.full(n_dofs, -1, np.int64)
        index[order] = np.arange(order.size)
        if not np.array_equal(index[order], np.arange(order.size)):
            raise ValueError("compliance blocks overlap: a dof is in two blocks")
        diag = np.zeros(order.size)
        diag[block_dofs.size:] = np.concatenate([np.zeros(0)] + [np.asarray(v, float) for _, v in diagonals])
        start = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
        block = np.full(order.size, -1, np.int64)
        block[:block_dofs.size] = np.repeat(np.arange(len(sizes)), sizes)
        offset = np.concatenate([[0], np.cumsum(sizes**2)]).astype(np.int64)
        values = np.concatenate([np.zeros(0)] + [np.asarray(v, float) for _, _, v in dense])
        return cls(order, index, diag, block, start, offset, values)

    def __len__(self) -> int:
        return self.order.size

    def arrays(self) -> tuple:
        """(diagonal, block, start, offset, values): what the kernels take."""
        return self.diagonal, self.block, self.start, self.offset, self.values

    def packed_rows(self, dof: np.ndarray) -> np.ndarray:
        """Rows of H over global dofs ``dof`` (nc, m) (-1: none) renumbered to packed dofs; a dof
        outside the compliance is an error (a contact on a dof without inverse mass)."""
        packed = np.where(dof >= 0, self.index[np.maximum(dof, 0)], -1)
        outside = (dof >= 0) & (packed < 0)
        if outside.any():
            raise ValueError(f"contact rows touch dofs without a compliance block: {np.unique(dof[outside])[:10]}")
        return packed


@numba.njit(cache=True)
def add_compliance(v, d, a, diagonal, block, start, offset, values):
    """v += M̂⁻¹ e_d a (packed v, d): the velocity change of a generalised impulse ``a`` on dof
    ``d`` (column d of a symmetric block, read as its row: contiguous, as the block's dofs are)."""
    b = block[d]
    if b < 0:
        v[d] += diagonal[d] * a
        return
    s0 = start[b]
    size = start[b + 1] - s0
    o = offset[b] + (d - s0) * size
    for q in range(size):
        v[s0 + q] += values[o + q] * a


@numba.njit(cache=True, inline="always")
def add_contact_impulse(v, c, dn, dt, dof, hn, ht, diagonal, block, start, offset, values):
    """v += M̂⁻¹ H_c (dn, dt) (packed): the velocity change of an impulse change (dn, dt) of contact c."""
    for k in range(dof.shape[1]):
        d = dof[c, k]
        if d >= 0:
            a = hn[c, k] * dn + ht[c, k] * dt
            if block[d] < 0:  # 1x1 block, inline
                v[d] += diagonal[d] * a
            else:
                add_compliance(v, d, a, diagonal, block, start, offset, values)


@numba.njit(cache=True, inline="always")
def contact_coupling(c, d, dof, hn, ht, diagonal, block, start, offset, values):
    """(nn, nt, tn, tt): the (2, 2) block H_cᵀ M̂⁻¹ H_d between contacts c and d (packed rows).
    Per dof of c, its row of M̂⁻¹ is located once: a 1x1 block couples with that same dof of d
    only, a dense block with the dofs of d in it: a lookup of the general entry per pair of dofs
    made the Delassus blocks a large part of a small mixture's time (benchmarks/results/delassus_blocks.md)."""
    nn = nt = tn = tt = 0.0
    m = dof.shape[1]
    for a in range(m):
        da = dof[c, a]
        if da < 0:
            continue
        cn, ct = hn[c, a], ht[c, a]
        b = block[da]
        row = 0  # where row da of its dense block starts, minus the block's first dof
        if b >= 0:
            s0 = start[b]
            row = offset[b] + (da - s0) * (start[b + 1] - s0) - s0
        for e in range(m):
            de = dof[d, e]
            if b < 0:  # a 1x1 block: da itself only
                if de != da:
                    continue
                w = diagonal[da]
            else:
                if de < 0 or block[de] != b:
                    continue
                w = values[row + de]
            nn += cn * w * hn[d, e]
            nt += cn * w * ht[d, e]
            tn += ct * w * hn[d, e]
            tt += ct * w * ht[d, e]
    return nn, nt, tn, tt


@numba.njit(cache=True)
def delassus_blocks(dof, hn, ht, diagonal, block, start, offset, values, W):
    """W[c] = H_c^T M̂⁻¹ H_c, the (2, 2) local Delassus block of every contact c (packed rows)."""
    for c in range(dof.shape[0]):
        wnn, wnt, _, wtt = contact_coupling(c, c, dof, hn, ht, diagonal, block, start, offset, values)
        W[c, 0, 0] = wnn
        W[c, 0, 1] = wnt
        W[c, 1, 0] = wnt
        W[c, 1, 1] = wtt


@numba.njit(cache=True)
def block_delassus(order, bstart, dof, hn, ht, diagonal, block, start, offset, values):
    """Dense W_BB of every block, row-major (2k, 2k) with rows n0, t0, n1, t1, ..., concatenated:
    (values, offsets (n_blocks + 1,))."""
    nb = bstart.shape[0] - 1
    woff = np.zeros(nb + 1, np.int64)
    for B in range(nb):
        k = bstart[B + 1] - bstart[B]
        woff[B + 1] = woff[B] + 4 * k * k
    wb = np.zeros(woff[nb])
    for B in range(nb):
        k = bstart[B + 1] - bstart[B]
        n2 = 2 * k
        for i in range(k):
            c = order[bstart[B] + i]
            for j in range(i, k):
                d = order[bstart[B] + j]
                nn, nt, tn, tt = contact_coupling(c, d, dof, hn, ht, diagonal, block, start, offset, values)
                o = woff[B]
                wb[o + (2 * i) * n2 + 2 * j] = nn
                wb[o + (2 * i) * n2 + 2 * j + 1] = nt
                wb[o + (2 * i + 1) * n2 + 2 * j] = tn
                wb[o + (2 * i + 1) * n2 + 2 * j + 1] = tt
                wb[o + (2 * j) * n2 + 2 * i] = nn
                wb[o + (2 * j + 1) * n2 + 2 * i] = nt
                wb[o + (2 * j) * n2 + 2 * i + 1] = tn
                wb[o + (2 * j + 1) * n2 + 2 * i + 1] = tt
    return wb, woff
