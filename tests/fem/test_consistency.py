"""f_int = dE/dx and K_t = df_int/dx by finite differences; invariance under rigid motions."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from compute.fem import FEBody, NeoHookean

from .meshes import mesh

MATERIAL = NeoHookean(young=1.0, poisson=0.495, density=1.0)
CASES = [(e, v) for e in ("T3", "T6") for v in ("standard", "mean_dilatation")]


def deformed_disk(element: str, volumetric: str) -> tuple[FEBody, np.ndarray]:
    """A curved (T6) disk and a large, non-homogeneous deformation of it (J from ~0.6 to ~1.6)."""
    X, cells = mesh(element, "disk")
    body = FEBody(X, cells, element, MATERIAL, volumetric)
    F = np.array([[1.4, 0.5], [-0.3, 0.7]])
    x = X @ F.T + [0.5, -0.2] + 0.15 * np.column_stack([np.sin(2 * X[:, 1]), np.cos(3 * X[:, 0])])
    assert body.inverted_elements(x).size == 0
    return body, x


def rotate(x: np.ndarray, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return x @ np.array([[c, -s], [s, c]]).T


@pytest.mark.parametrize("element,volumetric", CASES)
def test_tangent_against_finite_differences(element, volumetric):
    body, x = deformed_disk(element, volumetric)
    K = body.internal_force_and_tangent(x)[1].toarray()
    eps = 1e-6
    K_fd = np.empty_like(K)
    for j in range(body.n_dof):
        step = np.zeros(body.n_dof)
        step[j] = eps
        step = step.reshape(-1, 2)
        K_fd[:, j] = (body.internal_force(x + step) - body.internal_force(x - step)) / (2 * eps)
    assert np.abs(K - K_fd).max() / np.abs(K).max() < 1e-6
    assert np.abs(K - K.T).max() <= 1e-13 * np.abs(K).max()  # hyperelastic: symmetric


@pytest.mark.parametrize("element,volumetric", CASES)
def test_internal_force_is_the_energy_gradient(element, volumetric):
    body, x = deformed_disk(element, volumetric)
    f = body.internal_force(x)
    eps = 1e-6
    grad = np.empty(body.n_dof)
    for j in range(body.n_dof):
        step = np.zeros(body.n_dof)
        step[j] = eps
        step = step.reshape(-1, 2)
        grad[j] = (body.strain_energy(x + step) - body.strain_energy(x - step)) / (2 * eps)
    assert np.abs(f - grad).max() / np.abs(f).max() < 1e-6
    np.testing.assert_array_equal(body.internal_force_and_tangent(x)[0], f)


@pytest.mark.parametrize("element,volumetric", CASES)
def test_reference_state_is_stress_free(element, volumetric):
    body = deformed_disk(element, volumetric)[0]
    assert np.abs(body.internal_force(body.X)).max() < 1e-12 * MATERIAL.young
    assert body.strain_energy(body.X) == pytest.approx(0.0, abs=1e-14)


@settings(deadline=None, max_examples=10)
@given(st.floats(0.0, 2 * np.pi), st.sampled_from(CASES))
def test_objectivity(angle, case):
    """A rigid motion of a deformed state rotates forces, tangent and stresses, keeps the energy."""
    body, x = deformed_disk(*case)
    y = rotate(x, angle) + [3.0, -7.0]
    f, K = body.internal_force_and_tangent(x)
    g, L = body.internal_force_and_tangent(y)
    scale = np.abs(f).max()
    np.testing.assert_allclose(
        g.reshape(-1, 2), rotate(f.reshape(-1, 2), angle), atol=1e-12 * scale
    )
    np.testing.assert_allclose(f.reshape(-1, 2).sum(axis=0), 0.0, atol=1e-13 * scale)
    assert body.strain_energy(y) == pytest.approx(body.strain_energy(x), rel=1e-12)
    Q = np.kron(np.eye(body.n_nodes), rotate(np.eye(2), angle).T)  # block-diagonal rotation
    np.testing.assert_allclose(L.toarray(), Q @ K.toarray() @ Q.T, atol=1e-12 * np.abs(K).max())
    Q3 = np.eye(3)
    Q3[:2, :2] = rotate(np.eye(2), angle).T
    s, t = body.element_stresses(x), body.element_stresses(y)
    np.testing.assert_allclose(t.cauchy, Q3 @ s.cauchy @ Q3.T, atol=1e-12 * np.abs(s.cauchy).max())
    np.testing.assert_allclose(t.pressure, s.pressure, atol=1e-12 * np.abs(s.cauchy).max())
    np.testing.assert_allclose(t.von_mises, s.von_mises, rtol=1e-10)
