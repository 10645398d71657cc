"""The work of a step attempt, returned by the step's functions and summed by their callers."""

from __future__ import annotations

from dataclasses import dataclass, fields


@dataclass(frozen=True)
class StepStats:
    """Counts of one attempt, a step or a run: Newton iterations, contact-solve ``sweeps``,
    ``backtracks`` (damped Newton updates), ``fallbacks`` (attempts of the active-set Newton
    taken again by the fixed-point loop, compute.stepping.active_set) and ``cuts`` (failed
    attempts the step control cut, compute.stepping.control)."""

    newton_iterations: int = 0
    sweeps: int = 0
    backtracks: int = 0
    fallbacks: int = 0
    cuts: int = 0

    def __add__(self, other: "StepStats") -> "StepStats":
        return StepStats(*(getattr(self, f.name) + getattr(other, f.name) for f in fields(self)))


def spent(failure: BaseException) -> StepStats:
    """The work a failed attempt or step spent (its ``work``, set where it was raised; none if
    it failed before any)."""
    return getattr(failure, "work", None) or StepStats()


def carrying(failure: BaseException, work: StepStats) -> BaseException:
    """``failure`` with the work ``work`` it spent (StepFailure.work, SimulationError.work)."""
    failure.work = work
    return failure
