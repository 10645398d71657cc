"""A rigid disk on an inclined support (gravity tilted by α over a fixed, very large disk).

A disk (I = m r²/2) rolls without slipping when tan α ≤ 3μ, with acceleration (2/3) g sin α and a
contact point at rest (stick); otherwise it slides with a = g (sin α − μ cos α) and angular
acceleration 2 μ g cos α / r.
"""

import numpy as np
import pytest

from tests.compute.scenes import fixed_box_parameters, model_of

R_GROUND, r, g, h, T = 1.0e4, 0.5, 1.0, 1e-3, 0.5


def _run(tmp_path, mu, alpha):
    params = fixed_box_parameters((-2 * R_GROUND, 2 * R_GROUND, -2 * R_GROUND - 1, 10.0), mu,
                                  (g * np.sin(alpha), -g * np.cos(alpha)), h)
    params["materials"]["ground"] = {"kind": "rigid", "density": 1.0, "fixed": True}
    params["interactions"] = [{"between": ["rigid", "rigid"], "law": "coulomb", "friction": mu},
                              {"between": ["ground", "ground"], "law": "frictionless"},
                              {"between": ["rigid", "ground"], "law": "coulomb", "friction": mu}]
    model, stepper = model_of(tmp_path / "scene", params, [(0.0, -R_GROUND), (0.0, r + 1e-9)],
                              [R_GROUND, r], ["ground", "rigid"])
    state = model.initial_state()
    for _ in range(int(round(T / h))):
        state, rep = stepper.step(state, 0.0, 0.0)
    v = model.rigid.view(state.v)[1]
    return v, rep


@pytest.mark.parametrize("mu, tan_alpha", [(0.5, 0.3), (0.3, 0.5), (0.5, 1.0)])
def test_rolls_without_slipping_below_three_mu(tmp_path, mu, tan_alpha):
    alpha = np.arctan(tan_alpha)
    v, rep = _run(tmp_path, mu, alpha)
    assert v[0] / T == pytest.approx(2 / 3 * g * np.sin(alpha), rel=2e-3)
    assert v[0] + r * v[2] == pytest.approx(0.0, abs=1e-6)  # contact point sticks
    rn, rt = rep.contacts.impulse[0]
    assert abs(rt) < mu * rn


@pytest.mark.parametrize("mu, tan_alpha", [(0.2, 1.0), (0.1, 0.5), (0.0, 0.3)])
def test_slides_above_three_mu(tmp_path, mu, tan_alpha):
    alpha = np.arctan(tan_alpha)
    v, rep = _run(tmp_path, mu, alpha)
    assert v[0] / T == pytest.approx(g * (np.sin(alpha) - mu * np.cos(alpha)), rel=2e-3)
    assert -v[2] / T == pytest.approx(2 * mu * g * np.cos(alpha) / r, rel=2e-3, abs=1e-9)
    rn, rt = rep.contacts.impulse[0]
    assert abs(rt) == pytest.approx(mu * rn, rel=1e-9, abs=1e-15)  # on the Coulomb cone
