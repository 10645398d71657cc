"""Reference triangles: interpolation properties, gradients, quadrature exactness."""

from math import factorial

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from compute.fem.elements import T3, T6, element_type

ELEMENTS = [T3, T6]

points_in_triangle = st.tuples(st.floats(0.0, 1.0), st.floats(0.0, 1.0)).map(
    lambda p: np.array([p]) if p[0] + p[1] <= 1.0 else np.array([[1.0 - p[0], 1.0 - p[1]]])
)


def monomial_integral(p: int, q: int) -> float:
    """Exact integral of xi^p eta^q over the reference triangle."""
    return factorial(p) * factorial(q) / factorial(p + q + 2)


@pytest.mark.parametrize("element", ELEMENTS, ids=lambda e: e.name)
def test_kronecker_property_at_nodes(element):
    N, _ = element.basis(element.nodes)
    np.testing.assert_allclose(N, np.eye(element.n_nodes), atol=1e-15)


def test_t6_node_order_is_gmsh_triangle6():
    expected = [[0, 0], [1, 0], [0, 1], [0.5, 0], [0.5, 0.5], [0, 0.5]]
    np.testing.assert_array_equal(T6.nodes, expected)


@settings(deadline=None, max_examples=50)
@given(points_in_triangle)
def test_partition_of_unity_and_linear_completeness(xi):
    for element in ELEMENTS:
        N, dN = element.basis(xi)
        np.testing.assert_allclose(N.sum(axis=1), 1.0, atol=1e-14)
        np.testing.assert_allclose(N @ element.nodes, xi, atol=1e-14)
        dxi = np.einsum("man,ai->min", dN, element.nodes)[0]
        np.testing.assert_allclose(dxi, np.eye(2), atol=1e-14)


@settings(deadline=None, max_examples=50)
@given(points_in_triangle)
def test_gradients_against_finite_differences(xi):
    eps = 1e-6
    for element in ELEMENTS:
        _, dN = element.basis(xi)
        for r in range(2):
            step = np.zeros((1, 2))
            step[0, r] = eps
            fd = (element.basis(xi + step)[0] - element.basis(xi - step)[0]) / (2 * eps)
            np.testing.assert_allclose(dN[0, :, r], fd[0], atol=1e-8)


@pytest.mark.parametrize("element", ELEMENTS, ids=lambda e: e.name)
@pytest.mark.parametrize("kind", ["stiffness_rule", "mass_rule"])
def test_quadrature_exactness(element, kind):
    rule = getattr(element, kind)
    xi, eta = rule.points.T
    for p in range(rule.degree + 1):
        for q in range(rule.degree + 1 - p):
            exact = monomial_integral(p, q)
            assert rule.weights @ (xi**p * eta**q) == pytest.approx(exact, rel=1e-14, abs=1e-16)
    assert (rule.points >= 0).all() and (rule.points.sum(axis=1) <= 1).all()


def test_rule_degrees_match_the_element_needs():
    assert T6.stiffness_rule.degree >= 2  # det(dx/dxi) and adj(F) dN are of degree 2 for T6
    assert T6.mass_rule.degree >= 4  # N_a N_b of degree 4
    assert T3.mass_rule.degree >= 2


def test_element_type_lookup():
    assert element_type("T6") is T6
    with pytest.raises(ValueError, match="T3"):
        element_type("Q4")
