"""Step control: a step of size h is taken in sub-steps h / 2**d; an attempt that fails is
restarted from its own initial state at d + 1 (a cut), and the rest of the step goes on at that
depth. An attempt that fails at d = ``max_cuts`` stops the run with a diagnosis, the state left
as it was before the step. Attempts at d = ``max_cuts`` are told so (``deepest``): a failure that
only asks for a smaller step (a contact solve that missed its tolerance) is then kept as a miss
instead, and the step's reported contact residual, the largest of its accepted sub-steps', shows
it.

A step that needed cuts still advances time by h and counts as one step; its last impulses are
rescaled to the full h so that forces = impulse / h stay right in frames. Every sub-step's warm
start is the impulses rescaled to its own length (the same forces). Why: a step that starts
deeper than d = 0 used to warm-start its first sub-step h / 2**d with impulses over h, 2**d times
too large; the Gauss–Seidel solvers remove such a uniform excess only slowly
(benchmarks/results/warm_start_scale.md).

The depth is kept between steps (``state.cut_depth``): the next step starts at the depth the
last one ended with, and the depth goes down by one after ``GROW_AFTER`` steps that went no
deeper (by a cut or after a slow step, below). Why: in a compacting soft mixture the steps that fail whole come
in runs (a 500-disk mixture at P/E = 0.32: every few steps a whole step fails after its 25
Newton iterations, some 50 s of a run of 2–10 s steps, while its halves converge); starting
again from the whole step each time pays that failure again. A failure costs as much as 10–20
good steps, hence the slow growth (benchmarks/results/soft_mixture_steps.md).

A step that converged but was slow, its accepted sub-steps having taken more than
``SLOW_ITERATIONS`` Newton iterations each and more than ``SLOW_SWEEPS`` contact-solve sweeps per
iteration on average, sends the next steps one level deeper (kept one level above ``max_cuts``,
so that a failure can still be cut). Why: where a step's contact problems are hard, their cost
grows much faster than the step's length: in smaller steps the Newton iterations per unit time
hardly change while the sweeps fall, and the slow step comes before a far slower one. The
thresholds, judged per step on both counts, come from benchmarks/results/soft_mixture_steps.md
(figures also in benchmarks/results/design_figures.md).
"""

from __future__ import annotations

import copy

import numpy as np

from compute.errors import SimulationError, StepFailure

GROW_AFTER = 16  # steps without a new cut before the depth goes down by one
SLOW_ITERATIONS = 10  # a step with more Newton iterations per accepted sub-step than this
SLOW_SWEEPS = 30  # and more contact-solve sweeps per iteration than this sends the next ones deeper


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


def counts(stats: dict) -> tuple[int, int]:
    """(Newton iterations, contact-solve sweeps) counted so far in a stepper's ``stats``."""
    return stats["newton_iterations"], stats["nlgs_sweeps"]


def charge(rep, stats: dict, since: tuple[int, int]) -> None:
    """Give the report ``rep`` the Newton iterations and sweeps counted in ``stats`` since
    ``since`` (:func:`counts`): those of every attempt of the step, failed ones included."""
    rep.newton_iterations, rep.sweeps = (now - then for now, then in zip(counts(stats), since))


def slow(iterations: int, sweeps: int, sub_steps: int) -> bool:
    """Whether a step whose ``sub_steps`` accepted sub-steps took ``iterations`` Newton iterations
    and ``sweeps`` contact sweeps in all was slow (module docstring)."""
    return iterations > SLOW_ITERATIONS * sub_steps and sweeps > SLOW_SWEEPS * iterations


def step_with_cuts(attempt, state, h: float, max_cuts: int, stats: dict):
    """Advance ``state`` by h with ``attempt(state, h, deepest) -> StepReport`` (which raises
    StepFailure; ``deepest``: d = ``max_cuts``) in sub-steps h / 2**d, d from ``state.cut_depth``,
    one level deeper after each failing attempt (the rest of the step goes on at that depth); the
    next step starts one level deeper still if this one was slow. Raises SimulationError (state
    restored) when an attempt fails at depth ``max_cuts``. The report is the last sub-step's, with
    the Newton iterations and sweeps of all the step's attempts (counted by them in ``stats``), its
    ``cuts`` (failed attempts), ``sub_steps`` (accepted ones), and the largest contact
    ``residual``, ``max_penetration`` and ``hold_torque`` of the accepted sub-steps (a penetration left at the
    start of an early sub-step is not hidden by a later one's)."""
    t0, s0 = state.time, state.step
    since = counts(stats)
    snap = snapshot(state)
    depth0 = depth = min(state.cut_depth, max_cuts)
    units, done, rep, cuts, sub_steps = 2**max_cuts, 0, None, 0, 0  # progress in units of h / 2**max_cuts
    iterations = sweeps = 0  # of the accepted sub-steps
    residual = penetration = torque = 0.0
    over = h  # the step length the impulses in state.impulses are over
    while done < units:
        over = _rescale_impulses(state, over, h / 2**depth)
        before = snapshot(state)  # a failure restores impulses over the failed sub-step: `over`
        its0, sweeps0 = counts(stats)
        try:
            rep = attempt(state, h / 2**depth, depth >= max_cuts)
            residual = float(np.maximum(residual, rep.residual))  # NaN stays
            penetration = max(penetration, rep.max_penetration)
            torque = max(torque, rep.hold_torque)
            done += units >> depth
            sub_steps += 1
            its1, sweeps1 = counts(stats)
            iterations, sweeps = iterations + its1 - its0, sweeps + sweeps1 - sweeps0
        except StepFailure as exc:
            if depth >= max_cuts:
                restore(state, snap)
                cut = f"; the step failed down to sub-steps h / {2**depth} = {h / 2**depth:.4g} (h = {h:.4g})" if depth else ""
                raise SimulationError(f"step {s0 + 1}: {exc}{cut}") from None
            restore(state, before)
            stats["cuts"] += 1
            cuts += 1
            depth += 1
    rep.cuts, rep.sub_steps, rep.residual, rep.max_penetration = cuts, sub_steps, residual, penetration
    rep.hold_torque = torque
    charge(rep, stats, since)
    if slow(iterations, sweeps, sub_steps) and depth < max_cuts - 1:
        depth += 1
    state.cut_accepted = 0 if depth > depth0 else state.cut_accepted + 1
    state.cut_depth = depth
    if depth and state.cut_accepted >= GROW_AFTER:
        state.cut_depth, state.cut_accepted = depth - 1, 0
    state.time, state.step = t0 + h, s0 + 1
    _rescale_impulses(state, over, h)  # impulses of the last sub-step: to forces x h
    if rep.h != h:
        rep.contacts.impulse *= h / rep.h
    return rep


def _rescale_impulses(state, over: float, to: float) -> float:
    """Rescale the warm-start impulses of ``state`` from a step of length ``over`` to one of
    ``to`` (the same forces); returns ``to``."""
    if to != over:
        for fam in state.impulses:
            state.impulses[fam] = state.impulses[fam] * (to / over)
    return to

