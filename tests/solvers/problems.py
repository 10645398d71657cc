"""Random small frictional contact problems (ContactProblem) and their dense form, for the tests
of the contact solvers against the Lemke oracle."""

from __future__ import annotations

import numpy as np

from compute.contact.compliance import Compliance
from compute.contact.problem import ContactProblem
from compute.contact.rows import MAX_DOFS


def random_problem(rng, kind: str, nc: int, friction: float = 0.5) -> ContactProblem:
    """A problem with ``nc`` contacts over dofs of kind "rigid" (1x1 compliance blocks only),
    "soft" (one dense SPD block), "mixed" (both), "rank_deficient" (more contact rows than the
    dofs they touch, rigid). μ uniform in [0, friction] with some frictionless contacts; gap
    terms such that some velocity v0 keeps every contact open (a feasible problem: with more
    rows than dofs, random gaps could forbid every velocity), v_free closing about half of them."""
    n_rigid = {"rigid": 3 * nc, "soft": 0, "mixed": nc + 2, "rank_deficient": 3}[kind]
    n_soft = {"rigid": 0, "soft": 2 * nc + 4, "mixed": nc + 4, "rank_deficient": 0}[kind]
    n = n_rigid + n_soft
    diagonals = [(np.arange(n_rigid), rng.uniform(0.5, 2.0, n_rigid))] if n_rigid else []
    dense = []
    if n_soft:
        a = rng.normal(size=(n_soft, n_soft))
        block = np.linalg.inv(a @ a.T + n_soft * np.eye(n_soft))  # SPD compliance
        dense = [(np.array([0, n_soft]), n_rigid + np.arange(n_soft), block.ravel())]
    comp = Compliance.build(n, diagonals, dense)
    per_row = min(4, n)
    dof = np.full((nc, MAX_DOFS), -1, np.int64)
    hn, ht = np.zeros((nc, MAX_DOFS)), np.zeros((nc, MAX_DOFS))
    for c in range(nc):
        dof[c, :per_row] = rng.choice(n, per_row, replace=False)
        hn[c, :per_row] = rng.normal(size=per_row)
        ht[c, :per_row] = rng.normal(size=per_row)
    mu = np.where(rng.random(nc) < 0.2, 0.0, rng.uniform(0.0, friction, nc))
    v0 = rng.normal(size=n)
    gap_term = -np.einsum("ck,ck->c", hn, np.where(dof >= 0, v0[dof], 0.0)) + rng.uniform(0.0, 1.0, nc)
    return ContactProblem.of_rows(dof, hn, ht, comp, v0 + rng.normal(size=n), gap_term, mu, np.zeros((nc, 2)))


def dense_form(p: ContactProblem) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(C (n, n) compliance, H (n, 2 nc) columns n0, t0, n1, t1, ..., W = Hᵀ C H, b = Hᵀ v_free +
    (gap_term, 0)) of a problem, over its packed dofs."""
    n, nc = len(p.compliance), len(p)
    C = np.diag(p.compliance.diagonal).astype(float)
    st, off, vals = p.compliance.start, p.compliance.offset, p.compliance.values
    for k in range(len(st) - 1):
        d = np.arange(st[k], st[k + 1])
        C[np.ix_(d, d)] = vals[off[k]:off[k + 1]].reshape(len(d), len(d))
    H = np.zeros((n, 2 * nc))
    for c in range(nc):
        for k in np.flatnonzero(p.dof[c] >= 0):
            H[p.dof[c, k], 2 * c] += p.hn[c, k]
            H[p.dof[c, k], 2 * c + 1] += p.ht[c, k]
    b = H.T @ p.free_velocity()
    b[0::2] += p.gap_term
    return C, H, H.T @ C @ H, b


def bodies_problem(rng, nc: int, sizes=(6, 40, 60, 12), n_rigid: int = 9, crowded: int = 10) -> ContactProblem:
    """A frictionless problem over several soft bodies (dense SPD compliance blocks of ``sizes``
    dofs, the last left without contact) and ``n_rigid`` 1x1 dofs: each row touches up to 4 dofs,
    drawn from all of them (rows couple bodies with each other and with rigid dofs), except the
    first ``crowded`` rows, drawn from the first body and the rigid dofs (a body with more
    contacts than dofs)."""
    n_soft = sum(sizes)
    n = n_soft + n_rigid
    blocks, start = [], [0]
    for s in sizes:
        a = rng.normal(size=(s, s))
        blocks.append(np.linalg.inv(a @ a.T + s * np.eye(s)).ravel())
        start.append(start[-1] + s)
    comp = Compliance.build(n, [(n_soft + np.arange(n_rigid), rng.uniform(0.5, 2.0, n_rigid))],
                            [(np.array(start), np.arange(n_soft), np.concatenate(blocks))])
    touchable = np.concatenate([np.arange(start[-2]), n_soft + np.arange(n_rigid)])  # the last body: no contact
    dof = np.full((nc, MAX_DOFS), -1, np.int64)
    hn, ht = np.zeros((nc, MAX_DOFS)), np.zeros((nc, MAX_DOFS))
    first = np.concatenate([np.arange(start[1]), n_soft + np.arange(n_rigid)])
    for c in range(nc):
        k = int(rng.integers(1, 5))
        dof[c, :k] = rng.choice(first if c < crowded else touchable, k, replace=False)
        hn[c, :k] = rng.normal(size=k)
        ht[c, :k] = rng.normal(size=k)
    v0 = rng.normal(size=n)
    gap_term = -np.einsum("ck,ck->c", hn, np.where(dof >= 0, v0[dof], 0.0)) + rng.uniform(0.0, 1.0, nc)
    return ContactProblem.of_rows(dof, hn, ht, comp, v0 + rng.normal(size=n), gap_term, np.zeros(nc),
                                  np.zeros((nc, 2)))
