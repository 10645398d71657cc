"""Fits recover the parameters of synthetic data generated from the laws, with noise."""

from __future__ import annotations

import numpy as np
import pytest

from post import fits, models

PHI0, Z0 = 0.811, 3.6
PHI = np.linspace(0.815, 0.93, 14)


def _noisy(values: np.ndarray, relative: float, seed: int) -> np.ndarray:
    return values * (1 + relative * np.random.default_rng(seed).standard_normal(values.shape))


def _recovers(fit: fits.FitResult, truth: dict[str, float], rel: float) -> None:
    for name, value in truth.items():
        assert fit.params[name] == pytest.approx(value, rel=rel), name
        assert abs(fit.params[name] - value) < 5 * fit.stderr[name], name


@pytest.mark.parametrize("seed", range(3))
def test_platzer(seed):
    P = _noisy(models.platzer_pressure(PHI, 0.04, 0.95, PHI0), 0.02, seed)
    fit = fits.fit_platzer(PHI, P, PHI0)
    _recovers(fit, {"P0": 0.04, "phi_max": 0.95}, rel=0.05)
    assert fit.phi_range == (PHI[0], PHI[-1]) and fit.fixed == {"phi0": PHI0}
    assert fit.rms_relative == pytest.approx(0.02, rel=0.6)
    np.testing.assert_allclose(fit.predict(PHI), models.platzer_pressure(PHI, **fit.params, phi0=PHI0))


def test_platzer_without_noise_is_exact_and_its_modulus_is_the_derivative():
    fit = fits.fit_platzer(PHI, models.platzer_pressure(PHI, 0.04, 0.95, PHI0), PHI0)
    _recovers(fit, {"P0": 0.04, "phi_max": 0.95}, rel=1e-8)
    assert fit.rms < 1e-10
    h = 1e-7
    numeric = PHI * (fit.predict(PHI + h) - fit.predict(PHI - h)) / (2 * h)
    np.testing.assert_allclose(models.log_compaction_modulus(PHI, fit.params["P0"], fit.params["phi_max"]),
                               numeric, rtol=1e-6)


def test_platzer_with_phi_max_close_to_the_data():
    """phi_max only 1e-3 above the last point: the bound phi_max > max(phi) holds."""
    P = _noisy(models.platzer_pressure(PHI, 0.04, 0.931, PHI0), 0.01, 7)
    fit = fits.fit_platzer(PHI, P, PHI0)
    assert PHI[-1] < fit.params["phi_max"] == pytest.approx(0.931, abs=3e-4)


def test_single_particle_eq2():
    phi_p = np.linspace(0.79, 0.97, 12)
    y = _noisy(models.single_particle_pressure(phi_p, 0.14, 0.99), 0.02, 3)
    fit = fits.fit_single_particle(phi_p, y)
    _recovers(fit, {"b": 0.14, "phi_p_max": 0.99}, rel=0.05)
    assert fit.fixed == {"phi_p0": pytest.approx(np.pi / 4)}


def test_coordination_power_law():
    Z = models.coordination_law(PHI, 5.1, 0.5, PHI0, Z0)
    Z = Z + 0.03 * np.random.default_rng(4).standard_normal(Z.shape)
    below = np.array([0.80, 0.805])  # below jamming: left out of the fit
    fit = fits.fit_coordination(np.r_[below, PHI], np.r_[[3.1, 3.2], Z], PHI0, Z0)
    _recovers(fit, {"xi": 5.1, "alpha": 0.5}, rel=0.1)
    assert fit.phi_range == (PHI[0], PHI[-1])


def test_eq5_with_only_phi_max_free():
    fixed = {"b": 0.14, "xi": 5.1, "alpha": 0.5, "Z0": Z0, "phi0": PHI0}
    y = _noisy(models.eq5_pressure(PHI, 0.94, **fixed), 0.02, 5)
    fit = fits.fit_eq5(PHI, y, **fixed)
    assert list(fit.params) == ["phi_max"] and fit.fixed == fixed
    _recovers(fit, {"phi_max": 0.94}, rel=2e-3)
    assert fit.rms_relative == pytest.approx(0.02, rel=0.6)


def test_eq5_reduces_to_eq4():
    """Eq. 5 = (Z phi / 2 pi) P_p(phi) with Z from the power law and P_p from Eq. 2."""
    Z = models.coordination_law(PHI, 5.1, 0.5, PHI0, Z0)
    P_p = models.log_compaction(PHI, 0.14, 0.94, PHI0)
    np.testing.assert_allclose(models.eq5_pressure(PHI, 0.94, 0.14, 5.1, 0.5, Z0, PHI0),
                               Z * PHI / (2 * np.pi) * P_p)


def test_eq3_check():
    Z = models.coordination_law(PHI, 5.1, 0.5, PHI0, Z0)
    K = 1.1 * Z * PHI / (2 * np.pi) * models.log_compaction_modulus(PHI, 0.14, 0.99)
    check = fits.eq3_check(PHI, K, Z, b=0.14, phi_p_max=0.99)
    np.testing.assert_allclose(check.relative_error, 1 / 1.1 - 1)
    assert check.rms_relative == pytest.approx(1 - 1 / 1.1)


def test_too_few_points():
    with pytest.raises(ValueError):
        fits.fit_platzer(PHI[:2], models.platzer_pressure(PHI[:2], 0.04, 0.95, PHI0), PHI0)
