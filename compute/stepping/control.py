"""Step control: a failing step attempt is restarted from its initial state as two half steps,
up to ``max_cuts`` times; then the run stops with a diagnosis and the state is left as it was.

A step that needed cuts still advances time by h and counts as one step; its last impulses are
rescaled to the full h so that forces = impulse / h stay right in frames and warm starts.
"""

from __future__ import annotations

import copy

from compute.errors import SimulationError, StepFailure


def snapshot(state):
    """Everything a step attempt changes in ``state``."""
    return (state.q.copy(), state.v.copy(), state.time, state.step,
            None if state.q_detect is None else state.q_detect.copy(),
            copy.deepcopy(state.pairs), copy.deepcopy(state.impulses))


def restore(state, snap) -> None:
    q, v, t, s, qd, pairs, imp = snap
    state.q, state.v, state.time, state.step = q.copy(), v.copy(), t, s
    state.q_detect = None if qd is None else qd.copy()
    state.pairs = copy.deepcopy(pairs)
    state.impulses = copy.deepcopy(imp)


def step_with_cuts(attempt, state, h: float, max_cuts: int, stats: dict):
    """Advance ``state`` by h with ``attempt(state, h) -> StepReport`` (which raises StepFailure),
    halving failing attempts. Raises SimulationError (state restored) when cuts do not help."""
    t0, s0 = state.time, state.step
    snap = snapshot(state)
    try:
        rep = _cut(attempt, state, h, h, 0, max_cuts, s0, stats)
    except SimulationError:
        restore(state, snap)
        raise
    state.time, state.step = t0 + h, s0 + 1
    if rep.h != h:  # impulses of the last sub-step, over rep.h: rescale to forces x h
        for fam in state.impulses:
            state.impulses[fam] = state.impulses[fam] * (h / rep.h)
        rep.contacts.impulse *= h / rep.h
    return rep


def _cut(attempt, state, h_nominal, h, depth, max_cuts, step_index, stats):
    snap = snapshot(state)
    try:
        return attempt(state, h)
    except StepFailure as exc:
        if depth >= max_cuts:
            cut = f"; the step was cut {depth} times (h = {h_nominal:.4g} -> {h:.4g}) without success" if depth else ""
            raise SimulationError(f"step {step_index + 1}: {exc}{cut}") from None
        restore(state, snap)
        stats["cuts"] += 1
        first = _cut(attempt, state, h_nominal, 0.5 * h, depth + 1, max_cuts, step_index, stats)
        second = _cut(attempt, state, h_nominal, 0.5 * h, depth + 1, max_cuts, step_index, stats)
        second.sweeps += first.sweeps
        second.newton_iterations += first.newton_iterations
        second.cuts += first.cuts + 1
        return second
