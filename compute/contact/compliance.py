"""The inverse effective mass M̂⁻¹ seen by the contact solver, as a block-diagonal matrix.

Rigid-body and wall dofs are 1x1 blocks (1 / mass, 1 / inertia); a deformable body contributes
one dense block over its boundary dofs, taken from its factorised effective matrix
M̂ = M + h²θ² K_t. The contact solver only needs ``v += M̂⁻¹ H Δr`` restricted to dofs that
contacts touch, which these blocks give exactly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np


@dataclass
class Compliance:
    """Block-diagonal M̂⁻¹ over ``n_dofs`` dofs.

    ``diagonal`` (n_dofs,) the 1x1 blocks (0 for dofs in a dense block or not seen by contacts);
    ``block`` (n_dofs,) dense block of each dof (-1: none), ``pos`` (n_dofs,) its position in
    the block, ``start`` (n_blocks + 1,) offsets into ``dofs``, ``dofs`` the dofs of every dense
    block, ``offset`` (n_blocks + 1,) offsets into ``values``, the row-major entries of the
    (symmetric) blocks.
    """

    diagonal: np.ndarray
    block: np.ndarray
    pos: np.ndarray
    start: np.ndarray
    dofs: np.ndarray
    offset: np.ndarray
    values: np.ndarray

    @classmethod
    def build(cls, n_dofs: int, diagonals=(), dense=()) -> "Compliance":
        """From 1x1 blocks ``diagonals`` = [(dofs (k,), values (k,))] and dense blocks ``dense`` =
        [(start (B + 1,), dofs (m,), values)]: per group, block b over dofs[start[b]:start[b+1]]
        with row-major values (concatenated, sizes (start[b+1] - start[b])**2); empty blocks allowed."""
        diag = np.zeros(n_dofs)
        for d, values in diagonals:
            diag[d] = values
        block = np.full(n_dofs, -1, np.int64)
        pos = np.zeros(n_dofs, np.int64)
        sizes = np.concatenate([np.zeros(0, np.int64)] + [np.diff(st) for st, _, _ in dense])
        all_dofs = np.concatenate([np.zeros(0, np.int64)] + [np.asarray(d, np.int64) for _, d, _ in dense])
        values = np.concatenate([np.zeros(0)] + [np.asarray(v, float) for _, _, v in dense])
        start = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
        offset = np.concatenate([[0], np.cumsum(sizes**2)]).astype(np.int64)
        block[all_dofs] = np.repeat(np.arange(len(sizes)), sizes)
        pos[all_dofs] = np.arange(len(all_dofs)) - np.repeat(start[:-1], sizes)
        return cls(diag, block, pos, start, all_dofs, offset, values)

    def arrays(self) -> tuple:
        return self.diagonal, self.block, self.pos, self.start, self.dofs, self.offset, self.values


@numba.njit(cache=True)
def add_compliance(v, d, a, diagonal, block, pos, start, dofs, offset, values):
    """v += M̂⁻¹ e_d a: the velocity change of a generalised impulse ``a`` on dof ``d`` (column d of
    a symmetric block, read as its row: contiguous)."""
    b = block[d]
    if b < 0:
        v[d] += diagonal[d] * a
        return
    s0 = start[b]
    size = start[b + 1] - s0
    p = pos[d]
    o = offset[b] + p * size
    for q in range(size):
        v[dofs[s0 + q]] += values[o + q] * a


@numba.njit(cache=True, inline="always")
def add_contact_impulse(v, c, dn, dt, dof, hn, ht, diagonal, block, pos, start, dofs, offset, values):
    """v += M̂⁻¹ H_c (dn, dt): the velocity change of an impulse change (dn, dt) of contact c."""
    for k in range(dof.shape[1]):
        d = dof[c, k]
        if d >= 0:
            a = hn[c, k] * dn + ht[c, k] * dt
            if block[d] < 0:  # 1x1 block, inline
                v[d] += diagonal[d] * a
            else:
                add_compliance(v, d, a, diagonal, block, pos, start, dofs, offset, values)


@numba.njit(cache=True)
def delassus_blocks(dof, hn, ht, diagonal, block, pos, start, dofs, offset, values, W):
    """W[c] = H_c^T M̂⁻¹ H_c, the (2, 2) local Delassus block of every contact c."""
    nc, m = dof.shape
    for c in range(nc):
        wnn = wnt = wtt = 0.0
        for k in range(m):
            dk = dof[c, k]
            if dk < 0:
                continue
            bk = block[dk]
            if bk < 0:  # 1x1 block
                wnn += hn[c, k] * diagonal[dk] * hn[c, k]
                wnt += hn[c, k] * diagonal[dk] * ht[c, k]
                wtt += ht[c, k] * diagonal[dk] * ht[c, k]
                continue
            size = start[bk + 1] - start[bk]
            for l in range(m):
                dl = dof[c, l]
                if dl < 0 or block[dl] != bk:
                    continue
                cij = values[offset[bk] + pos[dk] * size + pos[dl]]
                wnn += hn[c, k] * cij * hn[c, l]
                wnt += hn[c, k] * cij * ht[c, l]
                wtt += ht[c, k] * cij * ht[c, l]
        W[c, 0, 0] = wnn
        W[c, 0, 1] = wnt
        W[c, 1, 0] = wnt
        W[c, 1, 1] = wtt
