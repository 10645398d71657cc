"""The fixed-order sums of compute.fixed_order against exact arithmetic and LAPACK."""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest

from compute.fixed_order import dot, least_squares


@pytest.mark.parametrize("n", (0, 1, 3, 4, 7, 1000))
def test_dot_is_the_exact_sum_to_rounding(n):
    """xᵀy against the exactly rounded sum of the exact products (fractions), for lengths that
    leave every remainder of the four partial sums."""
    rng = np.random.default_rng(n)
    x, y = rng.normal(size=n), rng.normal(size=n)
    exact = float(sum((Fraction(a) * Fraction(b) for a, b in zip(x, y)), Fraction(0)))
    scale = math.fsum(abs(a * b) for a, b in zip(x, y))
    assert abs(dot(x, y) - exact) <= 4 * n * np.finfo(float).eps * scale


@pytest.mark.parametrize("m", (1, 2, 4))
def test_least_squares_matches_lapack_on_full_rank_columns(m):
    """m independent columns of 500 entries: the coefficients of numpy's lstsq (LAPACK's SVD)."""
    rng = np.random.default_rng(10 + m)
    a, b = rng.normal(size=(m, 500)), rng.normal(size=500)
    expected = np.linalg.lstsq(a.T, b, rcond=None)[0]
    np.testing.assert_allclose(least_squares(a, b, 1e-10), expected, rtol=1e-10, atol=1e-12)


def test_least_squares_leaves_out_a_dependent_column():
    """A column that is a multiple of an earlier one (or zero) gets no coefficient, and the fit
    Σ c_j a_j is still the least-squares one (LAPACK's, which gives the minimum-norm c)."""
    rng = np.random.default_rng(3)
    a = rng.normal(size=(4, 300))
    a[2] = -2.0 * a[0]
    a[3] = 0.0
    b = rng.normal(size=300)
    c = least_squares(a, b, 1e-10)
    assert c[2] == 0.0 and c[3] == 0.0
    expected = np.linalg.lstsq(a.T, b, rcond=1e-10)[0]
    np.testing.assert_allclose(c @ a, expected @ a, rtol=1e-10, atol=1e-12)
