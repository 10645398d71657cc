"""Neo-Hookean law: derivatives against finite differences, small-strain limit, invariance."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from compute.fem.material import (
    NeoHookean,
    cauchy_stress,
    isochoric_cauchy,
    isochoric_energy,
    isochoric_pk1,
    isochoric_pk1_tangent,
    volumetric_response,
    von_mises,
)

MU, KAPPA = 0.7, 5.0


def rotation(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s], [s, c]])


# F = R(a) diag(s1, s2) R(b): every F with det F > 0, stretches in [0.3, 3].
deformation_gradients = st.builds(
    lambda a, b, s1, s2: rotation(a) @ np.diag([s1, s2]) @ rotation(b),
    st.floats(0.0, 2 * np.pi), st.floats(0.0, 2 * np.pi), st.floats(0.3, 3.0), st.floats(0.3, 3.0),
)


def fd_gradient(fun, F: np.ndarray, eps: float = 1e-6) -> np.ndarray:
    """Central difference of fun (returning an array of any shape) w.r.t. F (2, 2)."""
    out = []
    for k in range(2):
        for m in range(2):
            dF = np.zeros((2, 2))
            dF[k, m] = eps
            out.append((np.asarray(fun(F + dF)) - np.asarray(fun(F - dF))) / (2 * eps))
    return np.moveaxis(np.array(out).reshape((2, 2) + np.shape(out[0])), (0, 1), (-2, -1))


def energy_3d(F3: np.ndarray) -> float:
    """The same law written in 3D (independent of the 2D implementation)."""
    J = np.linalg.det(F3)
    I1 = np.sum(F3 * F3)
    return MU / 2 * (J ** (-2 / 3) * I1 - 3) + KAPPA / 4 * (J**2 - 1 - 2 * np.log(J))


@settings(deadline=None, max_examples=60)
@given(deformation_gradients)
def test_pk1_is_the_energy_gradient(F):
    P_fd = fd_gradient(lambda G: isochoric_energy(G, MU), F)
    np.testing.assert_allclose(isochoric_pk1(F, MU), P_fd, rtol=1e-6, atol=1e-8 * MU)


@settings(deadline=None, max_examples=60)
@given(deformation_gradients)
def test_tangent_is_the_pk1_derivative(F):
    P, A = isochoric_pk1_tangent(F, MU)
    np.testing.assert_array_equal(P, isochoric_pk1(F, MU))
    A_fd = fd_gradient(lambda G: isochoric_pk1(G, MU), F)
    np.testing.assert_allclose(A, A_fd, rtol=1e-6, atol=1e-7 * np.abs(A).max())
    np.testing.assert_allclose(A, A.transpose(2, 3, 0, 1), atol=1e-12 * np.abs(A).max())


@settings(deadline=None, max_examples=60)
@given(st.floats(0.05, 20.0))
def test_volumetric_derivatives(J):
    eps = 1e-6 * J
    U, dU, d2U = volumetric_response(J, KAPPA)
    up, um = volumetric_response(J + eps, KAPPA), volumetric_response(J - eps, KAPPA)
    assert dU == pytest.approx((up[0] - um[0]) / (2 * eps), rel=1e-6, abs=1e-8)
    assert d2U == pytest.approx((up[1] - um[1]) / (2 * eps), rel=1e-6)


@settings(deadline=None, max_examples=60)
@given(deformation_gradients)
def test_cauchy_from_the_3d_energy(F):
    """sigma = (1/J) dW3/dF3 F3^T, the 3D energy differentiated numerically; sigma_zz included."""
    F3 = np.eye(3)
    F3[:2, :2] = F
    eps = 1e-6
    P3 = np.zeros((3, 3))
    for k in range(3):
        for m in range(3):
            d = np.zeros((3, 3))
            d[k, m] = eps
            P3[k, m] = (energy_3d(F3 + d) - energy_3d(F3 - d)) / (2 * eps)
    sigma = P3 @ F3.T / np.linalg.det(F)
    atol = 1e-6 * (1 + np.abs(sigma).max())
    np.testing.assert_allclose(cauchy_stress(F, MU, KAPPA), sigma, atol=atol)


@settings(deadline=None, max_examples=40)
@given(deformation_gradients, st.floats(0.0, 2 * np.pi))
def test_objectivity_and_isotropy(F, angle):
    Q2 = rotation(angle)
    Q = np.eye(3)
    Q[:2, :2] = Q2
    sigma = cauchy_stress(F, MU, KAPPA)
    atol = 1e-12 * (1 + np.abs(sigma).max())
    np.testing.assert_allclose(cauchy_stress(Q2 @ F, MU, KAPPA), Q @ sigma @ Q.T, atol=atol)
    W = isochoric_energy(F, MU)
    assert isochoric_energy(F @ Q2, MU) == pytest.approx(W, rel=1e-12, abs=1e-14)


def test_small_strain_limit_is_plane_strain_linear_elasticity():
    material = NeoHookean(young=2.0, poisson=0.3, density=1.0)
    lam, mu = material.kappa - 2 * material.mu / 3, material.mu
    assert lam == pytest.approx(2.0 * 0.3 / (1.3 * 0.4))  # E nu / ((1 + nu)(1 - 2 nu))
    grad = np.array([[0.3, -0.8], [0.5, -0.6]])
    for eps in (1e-4, 1e-5):
        strain = eps * 0.5 * (grad + grad.T)
        linear = np.zeros((3, 3))
        linear[:2, :2] = 2 * mu * strain
        linear += lam * np.trace(strain) * np.eye(3)
        sigma = cauchy_stress(np.eye(2) + eps * grad, material.mu, material.kappa)
        np.testing.assert_allclose(sigma, linear, atol=10 * eps**2)


def test_reference_state_is_stress_free():
    np.testing.assert_allclose(cauchy_stress(np.eye(2), MU, KAPPA), 0.0, atol=1e-15)
    np.testing.assert_allclose(isochoric_pk1(np.eye(2), MU), 0.0, atol=1e-15)
    assert isochoric_energy(np.eye(2), MU) == 0.0
    assert volumetric_response(1.0, KAPPA)[:2] == (0.0, 0.0)


def test_isochoric_part_is_deviatoric():
    F = np.array([[1.4, 0.3], [-0.2, 0.8]])
    assert np.trace(isochoric_cauchy(F, MU)) == pytest.approx(0.0, abs=1e-14)


@pytest.mark.parametrize(
    "F", [np.diag([1.0, 0.0]), np.diag([-1.0, 1.0]), np.array([[0.0, 1.0], [1.0, 0.0]])]
)
def test_inadmissible_states_give_nan(F):
    P, A = isochoric_pk1_tangent(F, MU)
    assert np.isnan(P).all() and np.isnan(A).all()
    assert np.isnan(isochoric_pk1(F, MU)).all()
    assert np.isnan(isochoric_energy(F, MU))
    assert np.isnan(cauchy_stress(F, MU, KAPPA)).all()
    assert np.isnan(volumetric_response(np.linalg.det(F), KAPPA)).all()


def test_von_mises_of_simple_states():
    s = np.zeros((3, 3))
    s[0, 0] = 2.0
    assert von_mises(s) == pytest.approx(2.0)  # uniaxial
    s = np.zeros((3, 3))
    s[0, 1] = s[1, 0] = 1.5
    assert von_mises(s) == pytest.approx(np.sqrt(3) * 1.5)  # pure shear
    assert von_mises(-4.0 * np.eye(3)) == pytest.approx(0.0, abs=1e-14)  # hydrostatic


def test_material_constants():
    m = NeoHookean(young=3.0, poisson=0.495, density=2.0)
    assert 9 * m.kappa * m.mu / (3 * m.kappa + m.mu) == pytest.approx(3.0)
    assert (3 * m.kappa - 2 * m.mu) / (2 * (3 * m.kappa + m.mu)) == pytest.approx(0.495)
    for young, poisson, density in [(0.0, 0.3, 1.0), (1.0, 0.5, 1.0), (1.0, 0.3, -1.0)]:
        with pytest.raises(ValueError):
            NeoHookean(young, poisson, density)
