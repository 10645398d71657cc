"""MPRGP's block preconditioner (compute.solvers.body_blocks) against the dense Delassus operator."""

import numpy as np
import pytest

from compute.contact.delassus import Delassus
from compute.solvers.body_blocks import apply, preconditioner, row_groups
from compute.solvers.mprgp import unit_scaling
from tests.solvers.problems import random_problem


def scaled_dense(p):
    """S W_nn S (nc, nc) from the assembled W (an independent route: block-CSR assembly)."""
    w = Delassus.of_problem(p).dense()[::2, ::2]
    s = unit_scaling(np.ascontiguousarray(p.W[:, 0, 0]))
    return s[:, None] * w * s[None, :]


def built(p):
    c = p.compliance
    s = unit_scaling(np.ascontiguousarray(p.W[:, 0, 0]))
    return preconditioner(*row_groups(p.dof, c.block), s, p.dof, p.hn, *c.arrays())


@pytest.mark.parametrize("kind", ("soft", "mixed"))
def test_groups_hold_the_rows_of_each_soft_block(kind):
    """Every row touching a soft dof is in exactly one group (with two rows or more), no other row is."""
    for seed in range(5):
        p = random_problem(np.random.default_rng(seed), kind, 12)
        ptr, rows = row_groups(p.dof, p.compliance.block)
        soft = [c for c in range(len(p)) if any(d >= 0 and p.compliance.block[d] >= 0 for d in p.dof[c])]
        assert sorted(rows) == sorted(soft) if len(soft) >= 2 else rows.size == 0


@pytest.mark.parametrize("kind", ("soft", "mixed"))
def test_blocks_are_the_dense_operator_restricted(kind):
    """B_G is S W_nn S on the group's rows, and applying the preconditioner on a free set solves
    with B_G restricted to the free rows (off the free set: 0; rows in no group: the gradient)."""
    for seed in range(5):
        p = random_problem(np.random.default_rng(10 + seed), kind, 12)
        a = scaled_dense(p)
        pre = built(p)
        ptr, rows, boff, bval = pre[:4]
        for g in range(ptr.size - 1):
            idx = rows[ptr[g]:ptr[g + 1]]
            np.testing.assert_allclose(bval[boff[g]:boff[g + 1]].reshape(idx.size, idx.size), a[np.ix_(idx, idx)],
                                       rtol=1e-12, atol=1e-12)
        rng = np.random.default_rng(seed)
        for _ in range(3):  # the free set changes: the groups are factorised again
            y = np.where(rng.random(len(p)) < 0.7, rng.random(len(p)), 0.0)
            g_ = rng.normal(size=len(p))
            z = np.empty(len(p))
            apply(pre, y, g_, z)
            expected = np.where(y > 0, g_, 0.0)
            for g in range(ptr.size - 1):
                idx = rows[ptr[g]:ptr[g + 1]]
                f = idx[y[idx] > 0]
                if f.size >= 2:
                    expected[f] = np.linalg.solve(a[np.ix_(f, f)], g_[f])
            np.testing.assert_allclose(z, expected, rtol=1e-9, atol=1e-9)


def test_dependent_rows_keep_the_preconditioner_positive_definite():
    """Each row of a soft body twice (an interface held both ways, at its limit): the block is
    singular, and the preconditioner stays finite and positive definite (gᵀz > 0); MPRGP with it
    from the first iteration still reaches the tolerance."""
    from compute.solvers.mprgp import MPRGP

    p = random_problem(np.random.default_rng(3), "soft", 6)
    p.mu[:] = 0.0
    q = p.restricted(np.concatenate([np.arange(6), np.arange(6)]))
    assert np.linalg.matrix_rank(scaled_dense(q)) <= 6
    pre = built(q)
    rng = np.random.default_rng(0)
    for _ in range(5):
        g = rng.normal(size=12)
        z = np.empty(12)
        apply(pre, np.ones(12), g, z)
        assert np.all(np.isfinite(z)) and g @ z > 0
    report = MPRGP(1e-10, 1000, plain_iterations=0).solve(q)
    assert report.residual <= 1e-10
