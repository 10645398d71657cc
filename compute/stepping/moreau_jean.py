r"""One Moreau–Jean step: the sequence of a time step, visible in one place.

With h the time step and θ ∈ [1/2, 1]:

    M̂ (v⁺ - v_free) = H r                         (impulse balance)
    q⁺ = q⁻ + h ((1 - θ) v⁻ + θ v⁺)                (θ-method on positions)
    r from the contact solver: Signorini on g̃ + hθ u_n⁺, Coulomb on u_t⁺ (compute.contact.problem)

1. detection (Verlet lists, rebuilt past the skin) and narrow phase at q_n: rows of H, gaps;
2. every body group prepares the step (loads, x_n);
3. rigid disks and walls only: one contact solve with the diagonal compliance; with soft bodies,
   the Newton loop of :mod:`compute.stepping.newton` (one frictionless soft body with its
   rotation held: the active-set Newton of :mod:`compute.stepping.active_set`);
4. positions, time, contact memory.

With soft bodies a failing attempt is cut (:mod:`compute.stepping.control`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from compute.bodies import Load
from compute.contact import detection
from compute.contact.rows import ContactRows, generalised_impulse
from compute.errors import SimulationError, StepFailure
from compute import solvers
from compute.stepping import active_set, control
from compute.stepping.newton import solve_step
from compute.timing import TIMES


@dataclass
class StepReport:
    sweeps: int
    residual: float
    n_contacts: int  # contacts carrying a positive normal impulse
    max_penetration: float  # max(-gap) at the start of the step (of a cut step: of any sub-step), >= 0
    contacts: ContactRows
    newton_iterations: int = 1
    cuts: int = 0
    h: float = 0.0
    sub_steps: int = 1  # accepted sub-steps the step was taken in (compute.stepping.control)
    hold_torque: float = 0.0  # largest SoftBodies.hold_torques of the step (of a cut step: of its sub-steps)


class Stepper:
    """Advances a :class:`compute.state.State` of a :class:`compute.model.Model` by one step of the
    scene's time step ``h`` (a constant; cut sub-steps pass their own h down as arguments)."""

    MAX_CUTS = 4  # a step may be halved this many times before the run stops

    def __init__(self, model, solver=None):
        s = model.scene.solver
        self.model = model
        self.h, self.theta = s.time_step, s.theta
        self.solver = solver or solvers.for_model(s, model)
        self.newton_tolerance = s.newton_tolerance * model.diameter
        self.newton_max_iterations = s.newton_max_iterations
        self.gravity = tuple(model.scene.loading.gravity)
        self._counts = {"steps": 0, "newton_iterations": 0, "cuts": 0, "nlgs_sweeps": 0, "backtracks": 0,
                        "fallbacks": 0}

    @property
    def stats(self) -> dict:
        """Counts since the stepper was made: steps, Newton iterations, cuts, NLGS sweeps,
        backtracks, fallbacks (attempts of the active-set Newton taken again by the fixed-point
        loop, compute.stepping.active_set), and the soft groups' numeric factorisations (all
        attempts, stabilised ones too)."""
        return {**self._counts, "factorizations": sum(g.matrices.factorizations for g in self.model.soft if g.matrices),
                "stabilised_factorizations": sum(g.matrices.stabilised for g in self.model.soft if g.matrices)}

    def restart_point(self) -> None:
        """Make the next step depend on the state alone (called at checkpoints): soft groups drop
        the factorisations they would otherwise reuse, so that a run resumed from this
        checkpoint and the run that goes on from it take bitwise identical steps."""
        for g in self.model.soft:
            g.forget_factorisations()

    def step(self, state, pressure: float, wall_speed: float = 0.0) -> StepReport:
        """Advance ``state`` in place. Pressure control (walls pushed by ``pressure`` × length) or,
        under velocity control, walls moving inward at ``wall_speed``."""
        load = Load(pressure, wall_speed, self.gravity)
        if self.model.nonlinear:
            rep = control.step_with_cuts(lambda st, h, deepest: self._attempt(st, load, h, not deepest), state,
                                         self.h, self.MAX_CUTS, self._counts)
        else:
            try:
                rep = self._attempt(state, load, self.h)
            except StepFailure as exc:
                raise SimulationError(f"step {state.step + 1}: {exc}") from None
        self._counts["steps"] += 1
        return rep

    def _attempt(self, state, load: Load, h: float, misses_fail: bool = True) -> StepReport:
        m, th = self.model, self.theta
        with TIMES("detection"):
            if detection.needs_detection(m, state):
                detection.detect(m, state)
            contacts = detection.narrow_phase(m, state, branches=False)
        for g in m.groups:
            g.begin_step(state.q, state.v, h, th, load)
        # linear groups only: one contact solve is exact
        tol, max_it = (self.newton_tolerance, self.newton_max_iterations) if m.nonlinear else (np.inf, 1)
        solve = active_set.solve_step if m.active_set_newton else solve_step
        v, report, iterations = solve(m, contacts, state.v, h, th, self.solver, tol, max_it, self._counts, misses_fail)
        if not np.all(np.isfinite(v)):
            raise StepFailure(f"non-finite velocities after the contact solve (contact residual {report.residual:.3g} "
                              f"after {report.iterations} sweeps)")
        held = [g for g in m.soft if g.hold_rotation]
        hr = generalised_impulse(contacts.dof, contacts.hn, contacts.ht, contacts.impulse, m.n_dofs) if held else None
        torque = max((float(g.hold_torques(v, hr).max(initial=0.0)) for g in held), default=0.0)
        state.q += h * ((1.0 - th) * state.v + th * v)
        state.v = v
        state.time += h
        state.step += 1
        detection.store_impulses(m, state, contacts.impulse)
        return StepReport(report.iterations, report.residual, int(np.count_nonzero(contacts.impulse[:, 0] > 0.0)),
                          float(max(0.0, -contacts.gap.min())) if len(contacts) else 0.0, contacts,
                          newton_iterations=iterations, h=h, hold_torque=torque)
