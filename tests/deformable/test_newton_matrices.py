"""The batched Newton matrices of a soft group (compute.bodies.soft_matrix) against dense numpy:
the stabilisation level each body ends at, the solves, the reuse rule and the cached
compliance blocks."""

import numpy as np
import pytest

from compute.bodies.soft_matrix import IndefiniteMatrix, NewtonMatrices
from compute.fem import NeoHookean
from compute.fem.batch import BodyBatch
from pre.mesh import reference_disk_mesh

MATERIAL = NeoHookean(1.0, 0.495, 1.0)


def dense(batch, data):
    """(B, n, n) dense matrices of values (B, nnz) in the batch's pattern."""
    n = batch.n_dof
    out = np.zeros((len(data), n, n))
    rows = np.repeat(np.arange(n), np.diff(batch.indptr))
    out[:, rows, batch.indices] = data
    return out


@pytest.fixture(scope="module")
def pressed():
    """Four T6 disks squeezed by different amounts, and their M-hat at a large h."""
    m = reference_disk_mesh(92, "T6")
    X = np.stack([np.asarray(m.points)[:, :2] * r for r in (0.5, 0.6, 0.45, 0.55)])
    batch = BodyBatch(X, np.asarray(m.cells), "T6", MATERIAL, "mean_dilatation")
    squeeze = np.array([1.0, 0.97, 0.9, 0.8])[:, None, None]
    x = X * np.concatenate([np.ones_like(squeeze), squeeze], axis=2)
    f, k = np.zeros((4, batch.n_dof)), np.zeros((4, batch.indices.size))
    assert batch.internal_force_and_tangent(x, np.ones(4, bool), f, k).all()
    h, theta = 5.0, 1.0
    data = batch.mass_data + (h * theta) ** 2 * k
    g = np.zeros_like(k)
    batch.volumetric_geometric(x, np.ones(4, bool), g)
    return batch, data, (h * theta) ** 2 * g, (h, theta)


def expected_level(batch, data, g, key, shifts):
    """The first level (module docstring of soft_matrix) whose dense matrix is positive definite."""
    h, theta = key
    unit = MATERIAL.mu / (MATERIAL.density * batch.reference_areas.sum(axis=1) / np.pi)
    levels = []
    for b in range(batch.B):
        candidates = [data[b], data[b] - g[b]] + [data[b] - g[b] + s * (h * theta) ** 2 * unit[b] * batch.mass_data[b]
                                                  for s in shifts]
        eig = [np.linalg.eigvalsh(dense(batch, c[None])[0]).min() for c in candidates]
        levels.append(next((i for i, e in enumerate(eig) if e > 0.0), None))
    return levels


def test_levels_solves_and_blocks_match_dense(pressed):
    batch, data, g, key = pressed
    nm = NewtonMatrices(batch)
    every = np.ones(batch.B, bool)
    refactored = nm.update(data, lambda mask: g, key, 0.05, np.zeros(batch.B, bool), every)
    assert refactored.all()
    levels = expected_level(batch, data, g, key, nm.SHIFTS)
    assert nm.level.tolist() == levels
    assert levels[0] == 0 and max(levels) >= 1  # the fixture covers both cases
    # the factorised matrices are those of the chosen levels: solves against dense ones
    h, theta = key
    unit = MATERIAL.mu / (MATERIAL.density * batch.reference_areas.sum(axis=1) / np.pi)
    mats = []
    for b, lev in enumerate(levels):
        m = data[b] - (g[b] if lev >= 1 else 0.0)
        if lev >= 2:
            m = m + nm.SHIFTS[lev - 2] * (h * theta) ** 2 * unit[b] * batch.mass_data[b]
        mats.append(dense(batch, m[None])[0])
    rhs = np.random.default_rng(1).normal(size=(batch.B, batch.n_dof))
    x = nm.solve(rhs, every)
    for b in range(batch.B):
        np.testing.assert_allclose(mats[b] @ x[b], rhs[b], atol=1e-9 * np.abs(rhs[b]).max())
    # compliance blocks on ragged dof sets, then again with one body's set changed
    dofs = [np.array([0, 1, 7, 40]), np.array([3]), np.array([], int), np.array([5, 6, 100, 101, 300])]
    check_blocks(nm, dofs, mats)
    dofs[1] = np.array([2, 3, 9])  # one body's set changes: its block is recomputed, the others kept
    check_blocks(nm, dofs, mats)


def check_blocks(nm, dofs, mats):
    """The blocks of nm.compliance on the ragged ``dofs`` equal the dense inverses' submatrices."""
    start = np.concatenate([[0], np.cumsum([len(d) for d in dofs])])
    values = nm.compliance(start, np.concatenate(dofs))
    offsets = np.concatenate([[0], np.cumsum([len(d) ** 2 for d in dofs])])
    for b, d in enumerate(dofs):
        block = values[offsets[b]:offsets[b + 1]].reshape(len(d), len(d))
        expected = np.linalg.inv(mats[b])[np.ix_(d, d)]
        np.testing.assert_allclose(block, expected, rtol=1e-8, atol=1e-9 * np.abs(expected).max(initial=0.0))


def level_matrices(batch, data, g, key, shifts):
    """(B, levels, n, n) dense matrices of every stabilisation level (module docstring of soft_matrix)."""
    h, theta = key
    unit = MATERIAL.mu / (MATERIAL.density * batch.reference_areas.sum(axis=1) / np.pi)
    return np.array([[dense(batch, m[None])[0] for m in
                      [data[b], data[b] - g[b]] + [data[b] - g[b] + s * (h * theta) ** 2 * unit[b] * batch.mass_data[b]
                                                   for s in shifts]] for b in range(batch.B)])


def null_basis(c):
    """(n, n - 1) orthonormal basis of the vectors w with cᵀ w = 0."""
    q, _ = np.linalg.qr(np.column_stack([c, np.eye(c.size)]))
    return q[:, 1:]


def test_held_rotation_matches_the_dense_bordered_system(pressed):
    """With each body's rigid rotation held (c = M ρ), the level kept is the first whose matrix A
    is positive definite on cᵀ w = 0 (eigenvalues of Zᵀ A Z, dense); solves give the dense KKT
    solution [A −c; cᵀ 0] [Δ; λ] = [−R; −cᵀ v]; compliance blocks are those of Z (Zᵀ A Z)⁻¹ Zᵀ; a
    new held direction invalidates the kept factorisations not definite on it."""
    batch, data, g, key = pressed
    arm = batch.X - batch.centroids(batch.X)[:, None, :]
    c = batch.mass_times(np.stack([-arm[..., 1], arm[..., 0]], axis=2).reshape(batch.B, -1))
    mats = level_matrices(batch, data, g, key, NewtonMatrices.SHIFTS)
    Z = [null_basis(c[b]) for b in range(batch.B)]
    definite = np.array([[np.linalg.eigvalsh(Z[b].T @ a @ Z[b]).min() > 0.0 for a in mats[b]] for b in range(batch.B)])
    levels = definite.argmax(axis=1)
    assert (levels < expected_level(batch, data, g, key, NewtonMatrices.SHIFTS)).any()  # the hold matters here

    nm = NewtonMatrices(batch)
    every = np.ones(batch.B, bool)
    nm.hold(c)
    nm.update(data, lambda mask: g, key, 0.05, np.zeros(batch.B, bool), every)
    assert nm.level.tolist() == levels.tolist()
    held = [mats[b, lev] for b, lev in enumerate(levels)]
    rng = np.random.default_rng(2)
    rhs, v = rng.normal(size=(2, batch.B, batch.n_dof))
    end = v - nm.solve(rhs, every, v)
    n = batch.n_dof
    for b in range(batch.B):
        kkt = np.block([[held[b], -c[b][:, None]], [c[b][None, :], np.zeros((1, 1))]])
        expected = v[b] + np.linalg.solve(kkt, np.concatenate([-rhs[b], [-c[b] @ v[b]]]))[:n]
        np.testing.assert_allclose(end[b], expected, rtol=1e-7, atol=1e-9 * np.abs(expected).max())
    dofs = [np.array([0, 1, 7, 40]), np.array([3]), np.array([], int), np.array([5, 6, 100, 101, 300])]
    start = np.concatenate([[0], np.cumsum([len(d) for d in dofs])])
    values = nm.compliance(start, np.concatenate(dofs))
    offsets = np.concatenate([[0], np.cumsum([len(d) ** 2 for d in dofs])])
    for b, d in enumerate(dofs):
        G = Z[b] @ np.linalg.solve(Z[b].T @ held[b] @ Z[b], Z[b].T)
        block = values[offsets[b]:offsets[b + 1]].reshape(len(d), len(d))
        np.testing.assert_allclose(block, G[np.ix_(d, d)], rtol=1e-7, atol=1e-9 * np.abs(G).max())

    other = batch.mass_times(np.tile([1.0, 0.3], (batch.B, batch.n_nodes)))  # a translation held instead
    nm.hold(other)
    still = [np.linalg.eigvalsh(null_basis(other[b]).T @ held[b] @ null_basis(other[b])).min() > 0.0
             for b in range(batch.B)]
    assert nm.valid.tolist() == still and not all(still)


def test_reuse_rule(pressed):
    """A kept factorisation survives a small change (below the limit, same h), not a larger one,
    nor a new h, nor a forced refactorisation."""
    batch, data, g, key = pressed
    nm = NewtonMatrices(batch)
    every, none = np.ones(batch.B, bool), np.zeros(batch.B, bool)
    nm.update(data, lambda mask: g, key, 0.05, none, every)
    scale = np.abs(data).max(axis=1)
    small = data.copy()
    small[:, 0] += 0.01 * scale
    assert not nm.update(small, lambda mask: g, key, 0.05, none, every).any()
    large = data.copy()
    large[2, 0] += 0.2 * scale[2]
    assert nm.update(large, lambda mask: g, key, 0.05, none, every).tolist() == [False, False, True, False]
    forced = np.array([True, False, False, False])
    assert nm.update(large, lambda mask: g, key, 0.05, forced, every).tolist() == [True, False, False, False]
    assert nm.update(large, lambda mask: g, (key[0] / 2, key[1]), 0.05, none, every).all()


def test_no_positive_definite_level_names_the_bodies(pressed):
    batch, data, g, key = pressed
    nm = NewtonMatrices(batch)
    bad = data.copy()
    bad[1] *= -1.0  # negative definite: no level helps
    with pytest.raises(IndefiniteMatrix) as err:
        nm.update(bad, lambda mask: g, key, 0.05, np.zeros(batch.B, bool), np.ones(batch.B, bool))
    assert err.value.bodies.tolist() == [1]


def test_inverted_body_of_a_group_is_named():
    """A Newton iterate that inverts elements of one body of a several-body group stops the
    attempt with a diagnosis naming that body and its elements (not another exception)."""
    from compute.bodies import Load
    from compute.bodies.soft import SoftBodies
    from compute.errors import StepFailure

    m = reference_disk_mesh(30, "T3")
    X = np.stack([np.asarray(m.points)[:, :2] + (3.0 * b, 0.0) for b in range(3)])
    group = SoftBodies([10, 11, 12], X, np.asarray(m.cells), "T3", MATERIAL, "standard", 0, 0, 0)
    q = np.zeros(2 * X[:, :, 0].size)
    group.initial(q)
    v = np.zeros_like(q)
    step = group.begin_step(q, v, 1.0, 1.0, Load(0.0, 0.0, (0.0, 0.0)))
    flip = group.nodes(v)
    flip[1, :, 0] = -2.0 * X[1, :, 0] + 6.0  # body 11 mirrored about its centre: every element inverted
    with pytest.raises(StepFailure, match=r"body 11: \d+ inverted element"):
        group.free_velocity(step, v, np.zeros_like(v))
