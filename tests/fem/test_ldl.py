"""Batched sparse LDL^T (compute.fem.ldl) against dense numpy oracles.

Patterns: the FE bodies' own (hand-made disks and the gmsh reference disks, T3 and T6) and
random symmetric ones. Oracles: numpy.linalg.solve / inv / eigvalsh / cholesky on the dense
matrices.
"""

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from compute.fem import FEBody, NeoHookean
from compute.fem.ldl import SymbolicLDL, block_offsets
from pre.mesh import reference_disk_mesh

from .meshes import disk_mesh, to_t6

MATERIAL = NeoHookean(1.0, 0.495, 1.0)


def _body(kind: str) -> FEBody:
    """Body by kind: "gmsh T3" | "gmsh T6" (92-element reference disk), "disk T3" | "disk T6"
    (hand-made, 3 rings)."""
    if kind.startswith("gmsh"):
        m = reference_disk_mesh(92, kind[-2:])
        return FEBody(m.points, m.cells, kind[-2:], MATERIAL, "standard")
    X, cells = disk_mesh(3)
    if kind == "disk T6":
        X, cells = to_t6(X, cells, circle_radius=1.0)
        return FEBody(X, cells, "T6", MATERIAL, "mean_dilatation")
    return FEBody(X, cells, "T3", MATERIAL, "standard")


KINDS = ["disk T3", "disk T6", "gmsh T3", "gmsh T6"]


@pytest.fixture(scope="module", params=KINDS)
def body_ldl(request):
    body = _body(request.param)
    return body, SymbolicLDL(body.mass.indptr, body.mass.indices)


def dense(indptr, indices, data) -> np.ndarray:
    """Dense (n, n) matrix of values data (nnz,) in the CSR pattern."""
    n = indptr.size - 1
    return sp.csr_matrix((data, indices, indptr), shape=(n, n)).toarray()


def random_spd_values(indptr, indices, n_bodies, rng) -> np.ndarray:
    """(B, nnz) values of symmetric, strictly diagonally dominant (so SPD) matrices."""
    n = indptr.size - 1
    rows = np.repeat(np.arange(n), np.diff(indptr))
    out = np.empty((n_bodies, indices.size))
    for b in range(n_bodies):
        upper = np.triu(rng.uniform(-1.0, 1.0, (n, n)), 1)
        vals = (upper + upper.T)[rows, indices]
        shift = np.bincount(rows, np.abs(vals), n) + rng.uniform(0.1, 2.0, n)
        out[b] = vals + np.where(rows == indices, shift[rows], 0.0)
    return out


def dense_factors(sym: SymbolicLDL, lx: np.ndarray) -> np.ndarray:
    """Dense unit lower L (n, n) from the column storage of the strict lower triangle."""
    L = np.eye(sym.n)
    cols = np.repeat(np.arange(sym.n), np.diff(sym._lp))
    L[sym._li, cols] = lx
    return L


def test_ordering_is_the_cheapest_candidate_and_pattern_matches_dense_cholesky(body_ldl):
    body, sym = body_ldl
    assert sym.n == body.n_dof and sym.nnz == body.mass.nnz
    assert np.array_equal(np.sort(sym.perm), np.arange(sym.n))
    assert sym.flops == min(f for _, f in sym.candidates.values())
    assert sym.candidates[sym.ordering] == (sym.nnz_l, sym.flops)
    assert sym.flops < sym.candidates["natural"][1]
    indptr, indices = body.mass.indptr, body.mass.indices
    data = random_spd_values(indptr, indices, 1, np.random.default_rng(0))
    A = dense(indptr, indices, data[0])[np.ix_(sym.perm, sym.perm)]
    C = np.linalg.cholesky(A)
    lx, d = np.zeros((1, sym.nnz_l)), np.zeros((1, sym.n))
    assert sym.factorize(data, np.ones(1, bool), lx, d).tolist() == [0]
    L = dense_factors(sym, lx[0])
    np.testing.assert_allclose(L * np.sqrt(d[0]), C, atol=1e-12)
    # random values: no cancellation, the symbolic pattern is the exact structure of L
    assert np.count_nonzero(np.abs(np.tril(C, -1)) > 1e-14) == sym.nnz_l


def test_factorize_and_solve_a_batch_of_random_spd_matrices(body_ldl):
    body, sym = body_ldl
    rng = np.random.default_rng(1)
    B, n = 5, sym.n
    indptr, indices = body.mass.indptr, body.mass.indices
    data = random_spd_values(indptr, indices, B, rng)
    active = np.array([True, False, True, True, False])
    lx, d = np.full((B, sym.nnz_l), 7.0), np.full((B, n), 7.0)
    neg = sym.factorize(data, active, lx, d)
    assert neg.dtype == np.int64 and neg.tolist() == [0] * B
    assert (lx[~active] == 7.0).all() and (d[~active] == 7.0).all()
    rhs = rng.standard_normal((B, n))
    out = np.full((B, n), 7.0)
    sym.solve(lx, d, rhs, active, out)
    assert (out[~active] == 7.0).all()
    for b in np.flatnonzero(active):
        A = dense(indptr, indices, data[b])
        np.testing.assert_allclose(A @ out[b], rhs[b], atol=1e-10)
        np.testing.assert_allclose(out[b], np.linalg.solve(A, rhs[b]), rtol=1e-9, atol=1e-12)
    sym.solve(lx, d, rhs, active, rhs)  # in place
    np.testing.assert_array_equal(rhs[active], out[active])


def test_compliance_blocks_are_the_dense_inverse_submatrices(body_ldl):
    body, sym = body_ldl
    rng = np.random.default_rng(2)
    n = sym.n
    indptr, indices = body.mass.indptr, body.mass.indices
    sizes = [4, 0, 1, min(60, n), 7, 3]
    B = len(sizes)
    data = random_spd_values(indptr, indices, B, rng)
    active = np.array([True, True, True, True, True, False])
    lx, d = np.zeros((B, sym.nnz_l)), np.zeros((B, n))
    sym.factorize(data, active, lx, d)
    start = np.concatenate([[0], np.cumsum(sizes)])
    dofs = np.concatenate([np.sort(rng.choice(n, m, replace=False)) for m in sizes])
    offsets = block_offsets(start)
    assert offsets.tolist() == np.concatenate([[0], np.cumsum(np.square(sizes))]).tolist()
    values = np.full(offsets[-1], 7.0)
    sym.compliance(lx, d, start, dofs, active, values)
    for b in range(B):
        block = values[offsets[b]:offsets[b + 1]].reshape(sizes[b], sizes[b])
        if not active[b]:
            assert (block == 7.0).all()
            continue
        local = dofs[start[b]:start[b + 1]]
        inverse = np.linalg.inv(dense(indptr, indices, data[b]))
        np.testing.assert_allclose(block, inverse[np.ix_(local, local)], rtol=1e-9, atol=1e-12)
        np.testing.assert_array_equal(block, block.T)


@pytest.mark.parametrize("kind", ["gmsh T3", "gmsh T6", "disk T6"])
def test_negative_pivots_count_the_negative_eigenvalues_of_pressed_bodies(kind):
    """M + (h theta)^2 K_t of a squeezed disk: the geometric stiffness makes it indefinite for
    large steps; the negative pivots are its negative eigenvalues (Sylvester)."""
    body = _body(kind)
    sym = SymbolicLDL(body.mass.indptr, body.mass.indices)
    steps, squeezes = [0.01, 1.0, 3.0, 10.0, 100.0], [0.8, 0.6]
    data = np.array([body.mass.data + h**2 * body.internal_force_and_tangent(body.X * [1.0, s])[1].data
                     for s in squeezes for h in steps])
    B = data.shape[0]
    lx, d = np.zeros((B, sym.nnz_l)), np.zeros((B, sym.n))
    neg = sym.factorize(data, np.ones(B, bool), lx, d)
    expected = []
    for b in range(B):
        eig = np.linalg.eigvalsh(dense(body.mass.indptr, body.mass.indices, data[b]))
        assert np.abs(eig).min() > 1e-9 * np.abs(eig).max()  # inertia well defined
        expected.append(int((eig < 0).sum()))
    assert neg.tolist() == expected
    assert max(expected) > 0 and min(expected) == 0
    rhs = np.random.default_rng(3).standard_normal((B, sym.n))
    out = np.empty_like(rhs)
    sym.solve(lx, d, rhs, np.ones(B, bool), out)
    for b in range(B):
        A = dense(body.mass.indptr, body.mass.indices, data[b])
        np.testing.assert_allclose(A @ out[b], rhs[b], atol=1e-8 * np.abs(A).max())


def test_zero_or_non_finite_pivot_reports_minus_one():
    body = _body("gmsh T3")
    sym = SymbolicLDL(body.mass.indptr, body.mass.indices)
    indptr, indices = body.mass.indptr, body.mass.indices
    data = np.tile(body.mass.data, (3, 1))
    first = sym.perm[0]  # the leading pivot of P A P^T is A[first, first]
    diag = indptr[first] + np.flatnonzero(indices[indptr[first]:indptr[first + 1]] == first)[0]
    data[0, diag] = 0.0
    data[2, 5] = np.nan
    lx, d = np.zeros((3, sym.nnz_l)), np.zeros((3, sym.n))
    assert sym.factorize(data, np.ones(3, bool), lx, d).tolist() == [-1, 0, -1]


def test_rejects_a_non_symmetric_pattern():
    a = sp.csr_matrix(np.array([[1.0, 1.0], [0.0, 1.0]]))
    with pytest.raises(ValueError, match="symmetric"):
        SymbolicLDL(a.indptr, a.indices)


@settings(deadline=None, max_examples=40)
@given(n=st.integers(1, 25), density=st.floats(0.0, 0.5), seed=st.integers(0, 2**32 - 1))
def test_random_patterns_inertia_solve_and_compliance(n, density, seed):
    """Symmetric strictly diagonally dominant matrices with diagonal entries of both signs (the
    pivots never vanish) on random patterns, disconnected ones included (etree forests)."""
    rng = np.random.default_rng(seed)
    mask = np.triu(rng.random((n, n)) < density, 1)
    mask = mask | mask.T | np.eye(n, dtype=bool)
    pattern = sp.csr_matrix(mask.astype(float))
    off = np.triu(rng.uniform(-1, 1, (n, n)), 1) * mask
    off = off + off.T
    diag = rng.choice([-1.0, 1.0], n) * (np.abs(off).sum(axis=1) + rng.uniform(0.1, 1.0, n))
    A = off + np.diag(diag)
    data = np.vstack([A[mask], -A[mask]])  # two bodies, same pattern (row-major = CSR order)
    sym = SymbolicLDL(pattern.indptr, pattern.indices)
    lx, d = np.zeros((2, sym.nnz_l)), np.zeros((2, n))
    neg = sym.factorize(data, np.ones(2, bool), lx, d)
    eig = np.linalg.eigvalsh(A)
    assert neg.tolist() == [(eig < 0).sum(), (eig > 0).sum()]
    rhs = rng.standard_normal((2, n))
    out = np.empty((2, n))
    sym.solve(lx, d, rhs, np.ones(2, bool), out)
    np.testing.assert_allclose(out[0], np.linalg.solve(A, rhs[0]), rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(out[1], -np.linalg.solve(A, rhs[1]), rtol=1e-8, atol=1e-10)
    local = [np.sort(rng.choice(n, rng.integers(0, n + 1), replace=False)) for _ in range(2)]
    start = np.array([0, local[0].size, local[0].size + local[1].size])
    values = np.empty(block_offsets(start)[-1])
    sym.compliance(lx, d, start, np.concatenate(local), np.ones(2, bool), values)
    inverse = np.linalg.inv(A)
    o, m = block_offsets(start), [v.size for v in local]
    for b, sign in ((0, 1.0), (1, -1.0)):
        np.testing.assert_allclose(values[o[b]:o[b + 1]].reshape(m[b], m[b]),
                                   sign * inverse[np.ix_(local[b], local[b])], atol=1e-10)
