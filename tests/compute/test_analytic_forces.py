"""Contact forces of small static configurations against their closed-form values."""

import numpy as np
import pytest

from tests.compute.scenes import fixed_box_parameters, model_of


def _forces(report, h):
    """{(body_i, body_j): (fn, ft)} of the last step's contacts."""
    c = report.contacts
    return {(int(i), int(j)): (rn / h, rt / h) for i, j, (rn, rt) in zip(c.body_i, c.body_j, c.impulse)}


@pytest.mark.parametrize("friction", [0.0, 0.4])
def test_three_disk_pyramid_in_a_box(tmp_path, friction):
    """Two disks on the floor between the side walls, one on top: with frictionless walls the
    statics is determinate: disk–disk force mg/√3, side walls mg/(2√3), floor 3mg/2 each."""
    r, g, h = 0.5, 1.0, 1e-3
    eps = 1e-7
    bounds = (0.0, 4 * r, 0.0, 10 * r)
    centres = [(r, r + eps), (3 * r, r + eps), (2 * r, r + np.sqrt(3) * r + 3 * eps)]
    params = fixed_box_parameters(bounds, friction, (0.0, -g), h)
    model, stepper = model_of(tmp_path / "scene", params, centres, [r] * 3, ["rigid"] * 3)
    state = model.initial_state()
    for _ in range(300):
        state, rep = stepper.step(state, 0.0, 0.0)
    mg = model.rigid.mass[0] * g
    f = _forces(rep, h)
    tol = 1e-6
    assert f[(0, 2)][0] == pytest.approx(mg / np.sqrt(3), rel=tol)
    assert f[(1, 2)][0] == pytest.approx(mg / np.sqrt(3), rel=tol)
    assert f[(0, -1)][0] == pytest.approx(mg / (2 * np.sqrt(3)), rel=tol)  # left wall
    assert f[(1, -2)][0] == pytest.approx(mg / (2 * np.sqrt(3)), rel=tol)  # right wall
    assert f[(0, -3)][0] == pytest.approx(1.5 * mg, rel=tol)  # floor
    assert f[(1, -3)][0] == pytest.approx(1.5 * mg, rel=tol)
    for key, (fn, ft) in f.items():
        assert abs(ft) <= 1e-9 * mg, key  # symmetric statics needs no friction
    assert np.max(np.abs(state.v)) < 1e-9


def test_resting_disk_carries_its_weight_without_drift(tmp_path):
    """A disk on the floor: floor force = mg at every step, penetration stays at round-off."""
    r, h = 0.5, 1e-2
    params = fixed_box_parameters((0.0, 3.0, 0.0, 3.0), 0.3, (0.0, -9.81), h)
    model, stepper = model_of(tmp_path / "scene", params, [(1.5, r + 0.01)], [r], ["rigid"])
    state = model.initial_state()
    pens = []
    for _ in range(500):
        state, rep = stepper.step(state, 0.0, 0.0)
        pens.append(rep.max_penetration)
    assert _forces(rep, h)[(0, -3)][0] == pytest.approx(model.rigid.mass[0] * 9.81, rel=1e-9)
    assert max(pens) < 1e-3 * 2 * r
