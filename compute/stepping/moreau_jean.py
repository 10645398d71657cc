r"""One Moreau–Jean step: the sequence of a time step, visible in one place.

With h the time step and θ ∈ [1/2, 1]:

    M̂ (v⁺ - v_free) = H r                         (impulse balance)
    q⁺ = q⁻ + h ((1 - θ) v⁻ + θ v⁺)                (θ-method on positions)
    r from the contact solver: Signorini on g̃ + hθ u_n⁺, Coulomb on u_t⁺ (compute.contact.problem)

1. detection (Verlet lists, rebuilt past the skin) and narrow phase at q_n: rows of H, gaps
   (in a step at the full h, the frictionless segment–disk rows are made again at the
   end-of-step positions of the first Newton iterate, compute.contact.end_of_step);
2. every body group prepares the step (loads, x_n);
3. rigid disks and walls only: one contact solve with the diagonal compliance; with soft bodies,
   the Newton iterations of the step strategy the scene names (:mod:`compute.stepping.strategies`:
   the fixed-point loop of :mod:`compute.stepping.newton` or the active-set Newton of
   :mod:`compute.stepping.active_set`);
4. positions, time, contact memory: a new State (an attempt never changes the one it starts
   from, so a failed attempt needs no restoring).

With soft bodies a failing attempt is cut (:mod:`compute.stepping.control`). The work of every
attempt (compute.stepping.step_stats.StepStats) is returned with its report, or carried by its
failure, and summed by the callers.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from compute.bodies import Load
from compute.contact import detection
from compute.contact.end_of_step import EndOfStepSegmentRows
from compute.contact.rows import ContactRows, generalised_impulse
from compute.errors import SimulationError, StepFailure
from compute import solvers
from compute.state import State
from compute.stepping import control, strategies
from compute.stepping.groups import StepGroups
from compute.stepping.step_stats import StepStats, carrying, spent
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
    work: StepStats = field(default_factory=StepStats)  # of all the step's attempts, failed ones included


class Stepper:
    """Advances a :class:`compute.state.State` of a :class:`compute.model.Model` by one step of the
    scene's time step ``h`` (a constant; cut sub-steps pass their own h down as arguments). The
    model's body groups are reached through their protocols (``groups``,
    compute.stepping.groups); ``strategy`` iterates a step's equations (compute.stepping.strategies,
    the scene's ``solver.step``)."""

    # A step may be halved this many times before the run stops. Why 6 (h / 64): at P/E = 1 a soft
    # T3 disk pressed into a pore throat can need more than h / 16 to deform through it (the
    # 1500-disk κ = 0.2, μ = 0 run, benchmarks/results/high_pressure_newton.md); the steps that
    # do not fail never go below h / 8 (compute.stepping.control.SLOW_DEPTH).
    MAX_CUTS = 6

    def __init__(self, model, solver=None):
        s = model.scene.solver
        self.model = model
        self.groups = StepGroups(model.groups, model.n_dofs)
        self.h, self.theta = s.time_step, s.theta
        self.solver = solver or solvers.for_model(s, model)
        self.strategy = strategies.for_model(s, model)
        self.newton_tolerance = s.newton_tolerance * model.diameter
        self.newton_max_iterations = s.newton_max_iterations
        self.gravity = tuple(model.scene.loading.gravity)
        self.steps = 0
        self.work = StepStats()  # of every attempt since the stepper was made, failed steps' too

    @property
    def stats(self) -> dict:
        """Counts since the stepper was made: steps, Newton iterations, cuts, NLGS sweeps,
        backtracks, fallbacks (attempts of the active-set Newton taken again by the fixed-point
        loop, compute.stepping.active_set), and the soft groups' numeric factorisations (all
        attempts, stabilised ones too)."""
        w = self.work
        factorizations, stabilised = self.groups.factorisation_counts()
        return {"steps": self.steps, "newton_iterations": w.newton_iterations, "cuts": w.cuts,
                "nlgs_sweeps": w.sweeps, "backtracks": w.backtracks, "fallbacks": w.fallbacks,
                "factorizations": factorizations, "stabilised_factorizations": stabilised}

    def restart_point(self) -> None:
        """Make the next step depend on the state alone (called at checkpoints): soft groups drop
        the factorisations they would otherwise reuse, so that a run resumed from this
        checkpoint and the run that goes on from it take bitwise identical steps."""
        self.groups.forget_factorisations()

    def step(self, state, pressure: float, wall_speed: float = 0.0) -> tuple[State, StepReport]:
        """The state one step after ``state`` (which is left as it was) and the step's report.
        Pressure control (walls pushed by ``pressure`` × length) or, under velocity control, walls
        moving inward at ``wall_speed``. A failed step raises SimulationError carrying the work
        it spent (``work``, StepStats)."""
        load = Load(pressure, wall_speed, self.gravity)
        try:
            if self.groups.iterates:
                new, rep = control.step_with_cuts(lambda st, h, deepest: self._attempt(st, load, h, not deepest),
                                                  state, self.h, self.MAX_CUTS)
            else:
                try:
                    new, rep = self._attempt(state, load, self.h)
                except StepFailure as exc:
                    raise carrying(SimulationError(f"step {state.step + 1}: {exc}"), spent(exc)) from None
        except SimulationError as exc:
            self.work += spent(exc)
            raise
        self.work += rep.work
        self.steps += 1
        return new, rep

    def _attempt(self, state, load: Load, h: float, misses_fail: bool = True) -> tuple[State, StepReport]:
        """One attempt at a step of size h from ``state``: the state after it (a new State; the
        given one is not changed) and its report, or StepFailure carrying its work."""
        m, th = self.model, self.theta
        state = replace(state, pairs=dict(state.pairs), impulses=dict(state.impulses))  # the memory it changes
        with TIMES("detection"):
            if detection.needs_detection(m, state):
                detection.detect(m, state)
            contacts = detection.narrow_phase(m, state, branches=False)
        step = self.groups.begin_step(state.q, state.v, h, th, load)
        # linear groups only: one contact solve is exact
        tol, max_it = (self.newton_tolerance, self.newton_max_iterations) if step.iterates else (np.inf, 1)
        start_penetration = float(max(0.0, -contacts.gap.min())) if len(contacts) else 0.0
        # segment rows made again at the step's end, at the full step only (compute.contact.end_of_step)
        full = step.iterates and h == self.h
        end_rows = EndOfStepSegmentRows.of_step(m, state, contacts, h, th) if full else None
        v, report, work = self.strategy(step, contacts, state.v, self.solver, tol, max_it, misses_fail, end_rows)
        if not np.all(np.isfinite(v)):
            raise carrying(StepFailure(f"non-finite velocities after the contact solve (contact residual "
                                       f"{report.residual:.3g} after {report.iterations} sweeps)"), work)
        hr = (generalised_impulse(contacts.dof, contacts.hn, contacts.ht, contacts.impulse, m.n_dofs)
              if self.groups.holds_rotation else None)
        torque = step.hold_torque(v, hr) if hr is not None else 0.0
        detection.store_impulses(m, state, contacts.impulse)
        new = replace(state, q=state.q + h * ((1.0 - th) * state.v + th * v), v=v, time=state.time + h,
                      step=state.step + 1)
        return new, StepReport(report.iterations, report.residual, int(np.count_nonzero(contacts.impulse[:, 0] > 0.0)),
                               start_penetration, contacts,
                               newton_iterations=work.newton_iterations, h=h, hold_torque=torque, work=work)
