"""The step control (compute.stepping.control) with a scripted step attempt that fails above a
given h: cuts, the depth kept between steps and its growing back, time and impulses."""

from types import SimpleNamespace

import numpy as np
import pytest

from compute.errors import SimulationError, StepFailure
from compute.state import State
from compute.stepping import control


class ScriptedAttempt:
    """Accepts a sub-step of size h when h <= ``largest(step)`` (step: the step being taken, from
    1); records every h it was asked for."""

    def __init__(self, largest):
        self.largest, self.asked = largest, []
        self.stats = {"cuts": 0, "newton_iterations": 0, "nlgs_sweeps": 0}

    def __call__(self, state, h):
        self.asked.append(h)
        self.stats["newton_iterations"] += 2  # as the Newton loop counts: failing attempts too
        self.stats["nlgs_sweeps"] += 9
        state.time += h
        state.step += 1
        if h > self.largest(self.step_index) + 1e-15:
            raise StepFailure(f"too large a step (h = {h})")
        impulse = np.full((1, 2), h)  # an impulse proportional to its sub-step
        return SimpleNamespace(h=h, sweeps=9, newton_iterations=2, cuts=0, contacts=SimpleNamespace(impulse=impulse))


def take(attempt, state, steps, h=1.0, max_cuts=4):
    reports = []
    for k in range(steps):
        attempt.step_index = state.step + 1
        attempt.asked.append("|")
        reports.append(control.step_with_cuts(attempt, state, h, max_cuts, attempt.stats))
    return reports


def test_cut_depth_is_kept_then_grows_back():
    """Steps 1–3 converge only at h/4; later steps at any h. Step 1 fails whole and halved, then
    takes four quarters; steps 2–3 start as quarters (no failed attempt); after GROW_AFTER steps
    without a new cut the depth goes down one level at a time, back to whole steps."""
    attempt = ScriptedAttempt(lambda step: 0.25 if step <= 3 else 1.0)
    state = State(np.zeros(1), np.zeros(1))
    G = control.GROW_AFTER
    n = 2 * G + 4
    reports = take(attempt, state, n)
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
    take(attempt, state, 2)
    steps = " ".join(str(a) for a in attempt.asked).split("|")[1:]
    assert steps[0].split() == ["1.0", "0.5", "0.5"]
    assert steps[1].split() == ["0.5", "0.25"] + ["0.125"] * 8
    assert state.cut_depth == 3


def test_impulses_are_rescaled_to_the_whole_step():
    """Forces = impulse / h: the last sub-step's impulse, over h / 4, is scaled to the whole h."""
    attempt = ScriptedAttempt(lambda step: 0.25)
    state = State(np.zeros(1), np.zeros(1))
    rep, = take(attempt, state, 1)
    np.testing.assert_allclose(rep.contacts.impulse, 1.0)


def test_no_cut_helps_restores_the_state():
    attempt = ScriptedAttempt(lambda step: 0.01)
    state = State(np.zeros(1), np.zeros(1))
    with pytest.raises(SimulationError, match="down to sub-steps h / 4 = 0.25"):
        take(attempt, state, 1, max_cuts=2)
    assert state.step == 0 and state.time == 0.0 and state.cut_depth == 0
