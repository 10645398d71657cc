"""The step control (compute.stepping.control) with a scripted step attempt that fails above a
given h: cuts, the depth kept between steps and its growing back, time and impulses."""

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from compute.errors import SimulationError, StepFailure
from compute.state import State
from compute.stepping import control
from compute.stepping.step_stats import StepStats, carrying


class ScriptedAttempt:
    """Accepts a sub-step of size h when h <= ``largest(step)`` (step: the step being taken, from
    1); records every h it was asked for."""

    def __init__(self, largest, penetration=lambda sub_step: 0.0):
        self.largest, self.asked, self.penetration = largest, [], penetration

    def __call__(self, state, h, deepest):
        self.asked.append(h)
        work = StepStats(newton_iterations=2, sweeps=9)  # as the Newton loop counts: failing attempts too
        if h > self.largest(self.step_index) + 1e-15:
            raise carrying(StepFailure(f"too large a step (h = {h})"), work)
        impulse = np.full((1, 2), h)  # an impulse proportional to its sub-step
        sub_step = self.asked[::-1].index("|")  # attempts 1, 2, ... within the step
        return replace(state, time=state.time + h, step=state.step + 1), SimpleNamespace(
            h=h, sweeps=9, residual=1e-9 * sub_step, newton_iterations=2, cuts=0, work=work,
            max_penetration=self.penetration(sub_step), hold_torque=1e-4 * (sub_step == 4),
            contacts=SimpleNamespace(impulse=impulse))


def take(attempt, state, steps, h=1.0, max_cuts=4):
    """(the state after ``steps`` steps, their reports)."""
    reports = []
    for k in range(steps):
        attempt.step_index = state.step + 1
        attempt.asked.append("|")
        state, rep = control.step_with_cuts(attempt, state, h, max_cuts)
        reports.append(rep)
    return state, reports


def test_cut_depth_is_kept_then_grows_back():
    """Steps 1–3 converge only at h/4; later steps at any h. Step 1 fails whole and halved, then
    takes four quarters; steps 2–3 start as quarters (no failed attempt); after GROW_AFTER steps
    without a new cut the depth goes down one level at a time, back to whole steps."""
    attempt = ScriptedAttempt(lambda step: 0.25 if step <= 3 else 1.0)
    state = State(np.zeros(1), np.zeros(1))
    G = control.GROW_AFTER
    n = 2 * G + 4
    state, reports = take(attempt, state, n)
    steps = " ".join(str(a) for a in attempt.asked).split("|")[1:]
    assert steps[0].split() == ["1.0", "0.5", "0.25", "0.25", "0.25", "0.25"]
    assert all(s.split() == ["0.25"] * 4 for s in steps[1:G + 1])  # depth 2 kept for G steps
    assert all(s.split() == ["0.5"] * 2 for s in steps[G + 1:2 * G + 1])  # then depth 1 for G steps
    assert all(s.split() == ["1.0"] for s in steps[2 * G + 1:])  # then whole steps again
    assert len(steps) == n and len(steps[2 * G + 1:]) == 3
    assert [r.cuts for r in reports] == [2] + [0] * (n - 1)  # a kept depth is not a cut
    assert reports[0].newton_iterations == 2 * 6 and reports[0].sweeps == 9 * 6  # all attempts, failed ones too
    assert state.step == n and state.time == pytest.approx(n)


def test_failure_at_the_kept_depth_cuts_further():
    """A step that fails at its starting depth is cut below it, and the next starts there."""
    attempt = ScriptedAttempt(lambda step: 0.5 if step == 1 else 0.125)
    state = State(np.zeros(1), np.zeros(1))
    state, _ = take(attempt, state, 2)
    steps = " ".join(str(a) for a in attempt.asked).split("|")[1:]
    assert steps[0].split() == ["1.0", "0.5", "0.5"]
    assert steps[1].split() == ["0.5", "0.25"] + ["0.125"] * 8
    assert state.cut_depth == 3


def test_a_cut_step_reports_the_deepest_penetration_and_largest_residual_of_its_sub_steps():
    """Taken in four quarters, a step whose first quarter starts 2e-3 inside and whose last starts
    1e-6 inside reports 2e-3 (the last sub-step alone would hide it), the largest residual, and
    the largest hold torque (that of its second quarter)."""
    attempt = ScriptedAttempt(lambda step: 0.25, penetration=lambda sub_step: {3: 2e-3}.get(sub_step, 1e-6))
    state = State(np.zeros(1), np.zeros(1))
    state, (rep,) = take(attempt, state, 1)
    asked = attempt.asked[1:]
    assert asked == [1.0, 0.5, 0.25, 0.25, 0.25, 0.25]  # attempts 3..6 are the accepted quarters
    assert rep.sub_steps == 4 and rep.max_penetration == 2e-3
    assert rep.residual == pytest.approx(6e-9)
    assert rep.hold_torque == 1e-4


def test_impulses_are_rescaled_to_the_whole_step():
    """Forces = impulse / h: the last sub-step's impulse, over h / 4, is scaled to the whole h."""
    attempt = ScriptedAttempt(lambda step: 0.25)
    state = State(np.zeros(1), np.zeros(1))
    state, (rep,) = take(attempt, state, 1)
    np.testing.assert_allclose(rep.contacts.impulse, 1.0)


def test_every_sub_step_is_warm_started_with_the_same_forces():
    """Each attempt stores impulses h x (force 1) as a step does; every attempt, the first
    sub-step of a step started at a kept depth and those after a cut included, must be
    warm-started with impulses over its own h (force 1), not over the whole step or over the
    sub-step that failed."""
    scripted = ScriptedAttempt(lambda step: 0.25 if step <= 2 else 0.125)
    seen = []

    def attempt(state, h, deepest):
        seen.append(state.impulses["f"][0, 0] / h)  # the warm start's force
        scripted.step_index = attempt.step_index
        new, rep = scripted(state, h, deepest)
        return replace(new, impulses={"f": np.full((1, 2), h)}), rep

    attempt.asked = scripted.asked
    state = State(np.zeros(1), np.zeros(1), impulses={"f": np.full((1, 2), 1.0)})  # over the whole step h = 1
    state, _ = take(attempt, state, 4)
    assert len(seen) == 6 + 4 + 9 + 8  # 1, 0.5 failing then 4 quarters; 4 quarters; 1 quarter failing then 8 eighths; 8
    np.testing.assert_allclose(seen, 1.0)
    np.testing.assert_allclose(state.impulses["f"], 1.0)  # over the whole step again


def test_no_cut_helps_leaves_the_state_and_carries_the_work():
    """The failed step's state is the one it started from, unchanged; its failure carries the
    work of all three attempts and the two cuts."""
    attempt = ScriptedAttempt(lambda step: 0.01)
    state = State(np.zeros(1), np.zeros(1))
    with pytest.raises(SimulationError, match="down to sub-steps h / 4 = 0.25") as err:
        take(attempt, state, 1, max_cuts=2)
    assert state.step == 0 and state.time == 0.0 and state.cut_depth == 0
    assert err.value.work == StepStats(newton_iterations=2 * 3, sweeps=9 * 3, cuts=2)


def test_only_the_deepest_attempts_are_told_so():
    """A failure that only asks for a smaller step (a contact solve above its tolerance) fails
    every attempt above the deepest level; the deepest ones keep it: the step is taken there,
    and its reported residual is the largest of its sub-steps' (NaN counts as largest)."""

    class Missing(ScriptedAttempt):
        def __call__(self, state, h, deepest):
            new, rep = super().__call__(state, h, deepest)
            if not deepest:
                raise StepFailure("the contact solve missed its tolerance 2 times")
            rep.residual = self.residuals.pop(0)
            return new, rep

    for residuals, largest in (([1e-3, 5e-3, 2e-3, 1e-3], 5e-3), ([1e-3, np.nan, 2e-3, 1e-3], np.nan)):
        attempt = Missing(lambda step: 1.0)
        attempt.residuals = residuals
        state = State(np.zeros(1), np.zeros(1))
        state, (rep,) = take(attempt, state, 1, max_cuts=2)
        assert attempt.asked[1:] == [1.0, 0.5, 0.25, 0.25, 0.25, 0.25]
        assert rep.cuts == 2 and rep.sub_steps == 4 and state.time == pytest.approx(1.0)
        np.testing.assert_equal(rep.residual, largest)


class CostlyAttempt:
    """Always converges; a sub-step of size h costs ``cost(h)`` = (Newton iterations, sweeps)."""

    def __init__(self, cost):
        self.cost, self.asked = cost, []

    def __call__(self, state, h, deepest):
        self.asked.append(h)
        its, sweeps = self.cost(h)
        return replace(state, time=state.time + h, step=state.step + 1), SimpleNamespace(
            h=h, sweeps=sweeps, residual=1e-9, newton_iterations=its, cuts=0, max_penetration=0.0, hold_torque=0.0,
            work=StepStats(newton_iterations=its, sweeps=sweeps), contacts=SimpleNamespace(impulse=np.zeros((1, 2))))


def _slow_above(h_slow, its, sweeps):
    return lambda h: (its, sweeps) if h > h_slow else (2, 10)


SLOW = control.SLOW_ITERATIONS + 1


@pytest.mark.parametrize("its, sweeps, deeper", [
    (SLOW, SLOW * control.SLOW_SWEEPS + 1, True),
    (SLOW, SLOW * control.SLOW_SWEEPS, False),  # many iterations, easy contact solves
    (SLOW - 1, 100 * SLOW * control.SLOW_SWEEPS, False),  # few iterations
])
def test_a_slow_step_sends_the_next_ones_deeper(its, sweeps, deeper):
    """Sub-steps above h = 0.3 are slow (both counts above their limits, sweeps per iteration) or
    not. A slow step is kept (not taken again) and the next one starts a level deeper: step 1,
    whole and slow, is done; step 2, two slow halves, sends step 3 to quarters, which are not
    slow, and it stays there. Time still advances by whole steps, and the depth is not a cut."""
    attempt = CostlyAttempt(_slow_above(0.3, its, sweeps))
    state = State(np.zeros(1), np.zeros(1))
    state, reports = take(attempt, state, 4)
    steps = [s.split() for s in " ".join(str(a) for a in attempt.asked).split("|")[1:]]
    if deeper:
        assert steps == [["1.0"], ["0.5", "0.5"], ["0.25"] * 4, ["0.25"] * 4]
        assert [r.sub_steps for r in reports] == [1, 2, 4, 4] and state.cut_depth == 2
    else:
        assert steps == [["1.0"]] * 4 and state.cut_depth == 0
    assert all(r.cuts == 0 for r in reports) and state.time == pytest.approx(4.0)


def test_slowness_is_judged_over_the_whole_step():
    """One slow sub-step among cheap ones does not make a slow step: sub-steps of a step at
    h / 4 cost 2 * SLOW_ITERATIONS iterations (with many sweeps) only in the first quarter."""
    quarter = iter([(2 * SLOW, 2 * SLOW * (control.SLOW_SWEEPS + 1))] + [(2, 10)] * 3)
    attempt = CostlyAttempt(lambda h: next(quarter))
    state = State(np.zeros(1), np.zeros(1))
    state.cut_depth = 2
    state, (rep,) = take(attempt, state, 1)
    assert rep.sub_steps == 4 and state.cut_depth == 2


def test_slow_sub_steps_leave_a_level_for_cuts():
    """Depth from slowness stops one level above max_cuts: a failure there can still be cut."""
    attempt = CostlyAttempt(lambda h: (SLOW, SLOW * control.SLOW_SWEEPS + 1))
    state = State(np.zeros(1), np.zeros(1))
    state, _ = take(attempt, state, 4, max_cuts=3)
    assert state.cut_depth == 2 and min(a for a in attempt.asked if a != "|") == 0.25


def test_slowness_alone_goes_no_deeper_than_slow_depth():
    """With room for more cuts (max_cuts 6, the stepper's), slow steps send the next ones down to
    h / 2**SLOW_DEPTH only: the deeper levels are for steps that fail."""
    attempt = CostlyAttempt(lambda h: (SLOW, SLOW * control.SLOW_SWEEPS + 1))
    state = State(np.zeros(1), np.zeros(1))
    state, _ = take(attempt, state, 8, max_cuts=6)
    assert state.cut_depth == control.SLOW_DEPTH
    assert min(a for a in attempt.asked if a != "|") == 1.0 / 2**control.SLOW_DEPTH
