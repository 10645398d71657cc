"""A Newton step whose contact problem converges slowly ends on its true residuals.

Three soft T3 disks pressed together in a box by the walls, with friction, a large time step, a
loose contact tolerance (1e-3) and a Newton tolerance of 1e-9 diameters: each contact solve
stops after a sweep on its own tolerance, and its progress alone changes the velocities by more
than 1e-9 from one Newton iteration to the next, while contacts switch between stick and slip.
Judged on the size of the last correction, with Anderson mixing across those switches, these
steps took 100–300 iterations and were cut. Every step must end within 20 iterations, uncut,
and what it returns must satisfy the two residuals the loop claims, evaluated here
independently:

- the impulse balance h θ |M̂⁻¹ (R(v) - H r)|_∞, with R from the per-body reference
  implementation (FEBody) and a dense M̂ = M + h²θ² K_t at the step's end;
- the natural-map error of the contact law at (Hᵀ v, r), from the returned rows and impulses.
"""

import numpy as np
import pytest

from compute.bodies import Load
from compute.contact.problem import ContactProblem
from compute.contact.compliance import Compliance
from compute.contact.rows import generalised_impulse
from compute.contact.residual import natural_map_error
from tests.deformable import scenes

NEWTON_TOL, CONTACT_TOL = 1e-9, 1e-3
PRESSURE = 0.05


@pytest.fixture(scope="module")
def pressed(tmp_path_factory):
    return scenes.pressed_three(tmp_path_factory.mktemp("three"), 0.3, 1.0, NEWTON_TOL, CONTACT_TOL)


def dense_check(model, stepper, q0, v0, v, contacts) -> tuple[float, Compliance]:
    """(h θ |M̂⁻¹ (R(v) - H r)|_∞ over the soft bodies, the compliance M̂⁻¹ on the contact dofs),
    from FEBody and dense matrices at the step's end; the walls' 1x1 blocks from the model."""
    h, th = stepper.h, stepper.theta
    hr = generalised_impulse(contacts.dof, contacts.hn, contacts.ht, contacts.impulse, model.n_dofs)
    g = model.soft[0]
    touched = np.unique(contacts.dof[contacts.dof >= g.dofs.start])
    n = 2 * g.n_nodes
    worst, dofs, blocks, start = 0.0, [], [], [0]
    for k in range(g.B):
        body = scenes.fe_body(model, k)
        xn, vn, vk = (g.nodes(a)[k].ravel() for a in (q0, v0, v))
        x_theta = (xn + h * th * ((1 - th) * vn + th * vk)).reshape(-1, 2)
        f, kt = body.internal_force_and_tangent(x_theta)
        m = body.mass.toarray()
        inverse = np.linalg.inv(m + (h * th) ** 2 * kt.toarray())
        residual = m @ (vk - vn) + h * f - g.nodes(hr)[k].ravel()
        worst = max(worst, np.abs(inverse @ residual).max())
        local = touched[(touched >= g.dofs.start + k * n) & (touched < g.dofs.start + (k + 1) * n)]
        dofs.append(local)
        blocks.append(inverse[np.ix_(local - g.dofs.start - k * n, local - g.dofs.start - k * n)].ravel())
        start.append(start[-1] + len(local))
    walls = model.walls.begin_step(q0, v0, h, th, Load(PRESSURE, 0.0, stepper.gravity))  # the step's 1 / m̂
    compliance = Compliance.build(model.n_dofs, [(walls.dofs, walls.inverse)],
                                  [(np.array(start), np.concatenate(dofs), np.concatenate(blocks))])
    return h * th * worst, compliance


def test_slow_contact_solves_end_on_true_residuals(pressed):
    model, stepper, state = pressed
    for _ in range(8):
        q0, v0 = state.q.copy(), state.v.copy()
        state, rep = stepper.step(state, PRESSURE)
        assert rep.cuts == 0 and rep.newton_iterations <= 20
        c = rep.contacts
        assert np.count_nonzero(c.impulse[:, 0] > 0.0) >= 3
        balance, compliance = dense_check(model, stepper, q0, v0, state.v, c)
        assert balance <= 2 * NEWTON_TOL * model.diameter
        problem = ContactProblem.build(c, compliance, state.v, v0, stepper.h, stepper.theta)
        error = natural_map_error(c.dof, c.hn, c.ht, problem.W, problem.gap_term, c.mu, c.impulse, state.v)
        assert error <= 1.01 * CONTACT_TOL
