"""A free, spinning, translating, breathing deformable disk through the whole stepper (no
contact): theta = 1/2 conserves linear and angular momentum (implicit midpoint rule)."""

import numpy as np
import pytest

from tests.deformable import scenes


def momenta(model, state):
    body = scenes.fe_body(model)
    x = scenes.body_nodes(model, state.q)
    p = (body.mass @ scenes.body_nodes(model, state.v).ravel()).reshape(-1, 2)
    return p.sum(axis=0), float(np.sum(x[:, 0] * p[:, 1] - x[:, 1] * p[:, 0]))


@pytest.mark.parametrize("element", ["T3", "T6"])
def test_free_disk_conserves_momenta(tmp_path, element):
    params = scenes.parameters((-5.0, 5.0, -5.0, 5.0), element=element, time_step=0.05, theta=0.5,
                               control="velocity", newton_tolerance=1e-13)
    scenes.write(tmp_path, params, soft=[scenes.disk(92, element)])
    model, stepper, state = scenes.load(tmp_path)
    x = scenes.body_nodes(model, state.q).copy()
    scenes.body_nodes(model, state.v)[:] = np.array([0.3, -0.2]) + np.column_stack([-x[:, 1], x[:, 0]]) + 0.2 * x
    p0, L0 = momenta(model, state)
    for _ in range(100):
        state, rep = stepper.step(state, 0.0, 0.0)
        assert rep.n_contacts == 0
    p, L = momenta(model, state)
    assert np.abs(p - p0).max() <= 1e-10 * np.abs(p0).max()
    assert abs(L - L0) <= 1e-10 * abs(L0)
    # it moved, spun and deformed
    assert np.linalg.norm(scenes.body_nodes(model, state.q) - x, axis=1).max() > 1.0
    assert stepper.stats["cuts"] == 0


def test_held_rotation_stops_the_spin_and_keeps_the_linear_momentum(tmp_path):
    """solver.hold_rotation: after one step the spinning, translating, breathing disk's angular
    momentum about its centre of mass is zero, while its linear momentum is unchanged (the hold
    is a pure couple: its direction M ρ is orthogonal to every translation about that centre)."""
    params = scenes.parameters((-5.0, 5.0, -5.0, 5.0), element="T6", time_step=0.05, theta=0.5,
                               control="velocity", newton_tolerance=1e-13)
    params["solver"]["hold_rotation"] = True
    scenes.write(tmp_path, params, soft=[scenes.disk(92, "T6")])
    model, stepper, state = scenes.load(tmp_path)
    x = scenes.body_nodes(model, state.q).copy()
    scenes.body_nodes(model, state.v)[:] = np.array([0.3, -0.2]) + np.column_stack([-x[:, 1], x[:, 0]]) + 0.2 * x
    p0, L0 = momenta(model, state)
    body = scenes.fe_body(model)
    mx = (body.mass @ x.ravel()).reshape(-1, 2)
    arm = x - mx.sum(axis=0) / body.mass.sum() * 2.0  # about the centre of mass at the start of the step
    state, _ = stepper.step(state, 0.0, 0.0)
    p, _ = momenta(model, state)
    mv = (body.mass @ scenes.body_nodes(model, state.v).ravel()).reshape(-1, 2)
    assert abs(np.sum(arm[:, 0] * mv[:, 1] - arm[:, 1] * mv[:, 0])) <= 1e-10 * abs(L0)
    assert np.abs(p - p0).max() <= 1e-10 * np.abs(p0).max()
