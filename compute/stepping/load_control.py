"""Automatic load control within a pressure stage.

A stage's applied pressure goes from the previous stage's value P₀ (0 before the first stage) to
its target P₁ as P = P₀ + λ (P₁ - P₀), λ = ``state.load_fraction`` ∈ [0, 1]. Each step first tries
the whole remaining increment (so that a program whose jumps converge runs exactly as a plain
jump would). A step that fails (the Newton loop, an inverted or over-compressed element, an
indefinite matrix), even after the step control cut h (compute.stepping.control), is restored
and retried with half the increment Δλ; after ``GROW_AFTER`` accepted steps the increment
doubles again. When Δλ is at its floor ``MIN_INCREMENT`` (or the stage's load is already fully
applied) and the step still fails, the run stops with a diagnosis naming the stage, the
increment and the step's own diagnosis (which names the bodies).

Why cuts before splits: on the single particle some jumps go through only by cutting h and
others only by splitting the load (benchmarks/results/design_figures.md); cutting first keeps
every program that converged without load control converging the same way.
"""

from __future__ import annotations

from compute.errors import SimulationError
from compute.stepping.step_stats import StepStats, carrying, spent

MIN_INCREMENT = 2.0**-10  # floor of Δλ, a fraction of the stage's jump
GROW_AFTER = 2  # accepted steps at one increment before it doubles


def start_stage(state) -> None:
    """Reset the load fraction and increment at the start of a stage."""
    state.load_fraction, state.load_increment, state.load_accepted = 0.0, 1.0, 0


def applied(previous: float, target: float, fraction: float) -> float:
    """P = P₀ + λ (P₁ - P₀), exactly P₁ at λ = 1."""
    return target if fraction >= 1.0 else previous + fraction * (target - previous)


def controlled_step(stepper, state, previous: float, target: float, log):
    """One accepted step of the stage from ``previous`` to ``target`` (module docstring); returns
    (the new State, StepReport, applied pressure, number of increment halvings this step needed).
    The report's work (Newton iterations and sweeps) includes that of the failed increments.
    ``state`` keeps the increment a failure halved (its load ramp), nothing else."""
    halvings = 0
    failed = StepStats()  # work of the failed increments
    while True:
        remaining = 1.0 - state.load_fraction
        dl = min(state.load_increment, remaining)
        fraction = 1.0 if dl >= remaining else state.load_fraction + dl
        pressure = applied(previous, target, fraction)
        splittable = remaining > 0.0 and dl > MIN_INCREMENT
        try:
            new, rep = stepper.step(state, pressure)
        except SimulationError as exc:
            if not splittable:
                raise carrying(SimulationError(
                    f"stage {state.stage} (P = {target:.6g}): {exc}; at P = {pressure:.6g}, load increment "
                    f"{dl * (target - previous):.3g} ({dl:.3g} of the stage's jump from P = {previous:.6g}"
                    f"{', its floor' if remaining > 0.0 else ', the stage load fully applied'})"),
                    failed + spent(exc)) from None
            failed += spent(exc)
            state.load_increment = max(0.5 * dl, MIN_INCREMENT)
            state.load_accepted = 0
            halvings += 1
            log(f"stage {state.stage}: step {state.step + 1} failed at P = {pressure:.6g}; load increment "
                f"halved to {state.load_increment:.3g} of the jump ({exc})")
            continue
        rep.work = failed + rep.work
        rep.newton_iterations, rep.sweeps = rep.work.newton_iterations, rep.work.sweeps
        new.load_fraction = fraction
        new.load_accepted += 1
        if new.load_accepted >= GROW_AFTER and new.load_increment < 1.0:
            new.load_increment = min(1.0, 2.0 * new.load_increment)
            new.load_accepted = 0
        return new, rep, pressure, halvings
