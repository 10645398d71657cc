"""post.single_particle: the comparison of compaction curves and the fit of Eq. 2, on curves
generated from Eq. 2 with known parameters."""

import numpy as np
import pytest

from post import models
from post.single_particle import curve_errors, fit

P = np.geomspace(1e-3, 1.0, 16)


def _curve(b=0.14, phi_max=0.99):
    from scipy.optimize import brentq

    phi = np.array([brentq(lambda x: models.single_particle_pressure(np.array([x]), b, phi_max)[0] - p,
                           np.pi / 4 + 1e-12, phi_max - 1e-12) for p in P])
    return P, phi


def test_a_curve_against_itself_and_against_a_scaled_copy():
    p, phi = _curve()
    assert curve_errors(p, phi, p, phi) == pytest.approx((0.0, 0.0), abs=1e-14)
    e_phi, e_p = curve_errors(p, phi * 1.001, p, phi, phi_max=0.95)
    assert e_phi == pytest.approx(0.001, rel=1e-9)
    assert e_p > 0.0
    shifted = curve_errors(p * 1.1, phi, p, phi, phi_max=0.95)[1]  # 10 % more pressure at equal phi
    assert shifted == pytest.approx(0.1, rel=1e-6)


def test_fit_recovers_eq2_and_refuses_too_few_points():
    p, phi = _curve(0.2, 0.98)
    result, n = fit(p, phi, np.inf, 0.99)
    assert n == 16 and result.params["b"] == pytest.approx(0.2, rel=1e-6)
    assert result.params["phi_p_max"] == pytest.approx(0.98, rel=1e-8)
    with pytest.raises(ValueError, match="fewer than 3"):
        fit(p, phi, 1e-3, 0.99)


def test_curve_file_round_trip(tmp_path):
    from post.single_particle import write_curve

    p, phi = _curve()
    path = write_curve(tmp_path / "data" / "curve.csv", p, phi, "a test curve")
    data = np.loadtxt(path, delimiter=",", comments="#", skiprows=2)
    assert np.array_equal(data[:, 0], p) and np.array_equal(data[:, 1], phi)
    assert path.read_text().startswith("# a test curve\nP_over_E,phi_p\n")
