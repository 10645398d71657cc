"""The contact solver's packed compliance (compute.contact.compliance) against the dense matrix
it stands for, assembled here in the global numbering from the same blocks."""

import numpy as np
import pytest

from compute.contact.compliance import Compliance, add_contact_impulse
from compute.contact.problem import ContactProblem
from compute.contact.rows import MAX_DOFS


def scattered_blocks(rng, n):
    """Two dense SPD blocks on interleaved, unsorted global dofs and 1x1 blocks on some others;
    (diagonals, dense, the dense (n, n) matrix)."""
    perm = rng.permutation(n)
    soft = [perm[:5], perm[5:12]]
    single = perm[12:16]
    C = np.zeros((n, n))
    values = []
    for d in soft:
        a = rng.normal(size=(len(d), len(d)))
        m = a @ a.T + len(d) * np.eye(len(d))
        C[np.ix_(d, d)] = m
        values.append(m.ravel())
    inv_mass = rng.uniform(0.5, 2.0, len(single))
    C[single, single] = inv_mass
    dense = [(np.array([0, 5, 12]), np.concatenate(soft), np.concatenate(values))]
    return [(single, inv_mass)], dense, C


def test_packed_velocity_changes_equal_the_dense_compliance():
    """v_free + M̂⁻¹ H r from the packed kernels, unpacked, equals the dense product; the local
    Delassus blocks equal H_cᵀ C H_c; dofs in no block keep v_free."""
    rng = np.random.default_rng(3)
    n, nc = 20, 9
    diagonals, dense, C = scattered_blocks(rng, n)
    comp = Compliance.build(n, diagonals, dense)
    seen = np.flatnonzero(np.diag(C) != 0.0)
    dof = np.full((nc, MAX_DOFS), -1, np.int64)
    hn, ht = np.zeros((nc, MAX_DOFS)), np.zeros((nc, MAX_DOFS))
    for c in range(nc):
        dof[c, :4] = rng.choice(seen, 4, replace=False)
        hn[c, :4], ht[c, :4] = rng.normal(size=4), rng.normal(size=4)
    r = rng.normal(size=(nc, 2))
    v_free = rng.normal(size=n)
    p = ContactProblem.of_rows(dof, hn, ht, comp, v_free, np.zeros(nc), np.zeros(nc), r)
    v = p.free_velocity()
    for c in range(nc):
        add_contact_impulse(v, c, r[c, 0], r[c, 1], p.dof, p.hn, p.ht, *comp.arrays())
    H = np.zeros((n, 2 * nc))
    for c in range(nc):
        H[dof[c, :4], 2 * c], H[dof[c, :4], 2 * c + 1] = hn[c, :4], ht[c, :4]
    np.testing.assert_allclose(p.velocities(v), v_free + C @ H @ r.ravel(), rtol=1e-13, atol=1e-13)
    W = H.T @ C @ H
    for c in range(nc):
        np.testing.assert_allclose(p.W[c], W[2 * c:2 * c + 2, 2 * c:2 * c + 2], rtol=1e-13)
    np.testing.assert_allclose(p.generalised_impulse(n), H @ r.ravel(), rtol=1e-13, atol=1e-13)


def test_rows_on_a_dof_without_compliance_and_overlapping_blocks_are_errors():
    rng = np.random.default_rng(4)
    diagonals, dense, C = scattered_blocks(rng, 20)
    comp = Compliance.build(20, diagonals, dense)
    outside = int(np.flatnonzero(np.diag(C) == 0.0)[0])
    dof = np.full((1, MAX_DOFS), -1, np.int64)
    dof[0, 0] = outside
    with pytest.raises(ValueError, match="without a compliance block"):
        comp.packed_rows(dof)
    with pytest.raises(ValueError, match="overlap"):
        Compliance.build(20, diagonals + [(dense[0][1][:1], np.ones(1))], dense)
