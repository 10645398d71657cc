"""Patch tests and homogeneous plane-strain states against closed forms derived from W.

Closed forms. For F = diag(a, b) (plane strain, F_zz = 1), J = a b, I1 = a^2 + b^2 + 1 and
sigma = (1/J) dW/dF F^T gives, with U'(J) = kappa/2 (J - 1/J):

    sigma_xx = mu J^(-5/3) (a^2 - I1/3) + U'(J)
    sigma_yy = mu J^(-5/3) (b^2 - I1/3) + U'(J)
    sigma_zz = mu J^(-5/3) (1   - I1/3) + U'(J)

Uniaxial stress along x: a = lambda imposed, b solves sigma_yy(lambda, b) = 0 (scipy brentq).
Equibiaxial: a = b = lambda.
"""

import numpy as np
import pytest
from scipy.optimize import brentq

from compute.fem import FEBody, NeoHookean, cauchy_stress

from .meshes import mesh
from .newton import node_dofs, solve_static

MATERIAL = NeoHookean(young=1.0, poisson=0.45, density=1.0)
MU, KAPPA = MATERIAL.mu, MATERIAL.kappa
CASES = [(e, v) for e in ("T3", "T6") for v in ("standard", "mean_dilatation")]
DEFORMATIONS = [
    (np.array([[1.3, 0.4], [-0.25, 0.85]]), np.array([0.3, -0.2])),
    (np.array([[0.55, -0.5], [0.45, 0.9]]), np.array([-1.0, 2.0])),
]


def principal_cauchy(a: float, b: float) -> np.ndarray:
    """(sigma_xx, sigma_yy, sigma_zz) for F = diag(a, b), from the closed form above."""
    J = a * b
    I1 = a * a + b * b + 1.0
    dU = 0.5 * KAPPA * (J - 1.0 / J)
    return MU * J ** (-5.0 / 3.0) * (np.array([a * a, b * b, 1.0]) - I1 / 3.0) + dU


@pytest.mark.parametrize("element,volumetric", CASES)
@pytest.mark.parametrize("F,c", DEFORMATIONS)
def test_patch_test(element, volumetric, F, c):
    """x = F X + c on the boundary of an irregular patch (curved interior edges for T6)."""
    X, cells = mesh(element, "patch")
    body = FEBody(X, cells, element, MATERIAL, volumetric)
    exact = X @ F.T + c
    interior = np.setdiff1d(np.arange(body.n_nodes), body.boundary)
    f = body.internal_force(exact)
    assert np.abs(f.reshape(-1, 2)[interior]).max() < 1e-13

    start = exact.copy()
    start[interior] += 0.002 * np.random.default_rng(0).uniform(-1, 1, (interior.size, 2))
    x = solve_static(body, start, node_dofs(body.boundary))
    np.testing.assert_allclose(x, exact, rtol=0, atol=1e-10)

    sigma = body.element_stresses(x).cauchy  # the pointwise law (tested alone) at the same F
    expected = np.broadcast_to(cauchy_stress(F, MU, KAPPA), sigma.shape)
    np.testing.assert_allclose(sigma, expected, atol=1e-10)


@pytest.mark.parametrize("element,volumetric", CASES)
def test_uniaxial_plane_strain_stress(element, volumetric):
    """Square [0,1]^2 stretched to lambda along x on rollers, lateral sides free."""
    stretch = 1.25
    b = brentq(lambda b: principal_cauchy(stretch, b)[1], 0.3, 1.0, xtol=1e-15, rtol=1e-15)
    X, cells = mesh(element, "patch")
    body = FEBody(X, cells, element, MATERIAL, volumetric)
    left, right = np.flatnonzero(np.isclose(X[:, 0], 0.0)), np.flatnonzero(np.isclose(X[:, 0], 1.0))
    origin = np.flatnonzero((X == 0.0).all(axis=1))
    fixed = np.concatenate([node_dofs(left, (0,)), node_dofs(right, (0,)), node_dofs(origin, (1,))])
    x = X.copy()
    for lam in np.linspace(1.0, stretch, 4)[1:]:  # a few load steps
        x[:, 0] *= lam / x[right[0], 0]
        x = solve_static(body, x, fixed)

    np.testing.assert_allclose(x, X * [stretch, b], atol=1e-10)
    sxx, syy, szz = principal_cauchy(stretch, b)
    out = body.element_stresses(x)
    expected = np.diag([sxx, 0.0, szz])
    np.testing.assert_allclose(out.cauchy, np.broadcast_to(expected, out.cauchy.shape), atol=1e-10)
    np.testing.assert_allclose(out.pressure, -0.5 * sxx, atol=1e-10)
    mises = np.sqrt(0.5 * (sxx**2 + szz**2 + (sxx - szz) ** 2))
    np.testing.assert_allclose(out.von_mises, mises, atol=1e-10)
    reaction = body.internal_force(x).reshape(-1, 2)[right, 0].sum()
    assert reaction == pytest.approx(sxx * b, rel=1e-10)  # force = sigma_xx x current height


@pytest.mark.parametrize("element,volumetric", CASES)
@pytest.mark.parametrize("stretch", [0.85, 1.15])
def test_equibiaxial_plane_strain(element, volumetric, stretch):
    """Uniform lambda X on a (curved for T6) disk: stresses and the virial of the nodal forces,
    sum_a x_a (x) f_a = integral of sigma over the current body = sigma * area."""
    X, cells = mesh(element, "disk")
    body = FEBody(X, cells, element, MATERIAL, volumetric)
    x = stretch * X
    s, _, szz = principal_cauchy(stretch, stretch)
    out = body.element_stresses(x)
    expected = np.broadcast_to(np.diag([s, s, szz]), out.cauchy.shape)
    np.testing.assert_allclose(out.cauchy, expected, atol=1e-12)
    np.testing.assert_allclose(out.pressure, -s, atol=1e-12)
    virial = x.T @ body.internal_force(x).reshape(-1, 2)
    np.testing.assert_allclose(virial, s * body.area(x) * np.eye(2), atol=1e-12)
    assert body.area(x) == pytest.approx(stretch**2 * body.area(X), rel=1e-14)
