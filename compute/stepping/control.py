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
deeper (by a cut or after a slow step, below). Why: in a compacting soft mixture the steps that
fail whole come in runs (every few steps a whole step fails after all its Newton iterations
while its halves converge); starting again from the whole step each time pays that failure
again. A failure costs as much as many good steps, hence the slow growth
(benchmarks/results/soft_mixture_steps.md; figures in benchmarks/results/design_figures.md).

A step that converged but was slow, its accepted sub-steps having taken more than
``SLOW_ITERATIONS`` Newton iterations each and more than ``SLOW_SWEEPS`` contact-solve sweeps per
iteration on average, sends the next steps one level deeper, down to ``SLOW_DEPTH`` and at least
one level above ``max_cuts`` (so that a failure can still be cut): the deeper levels are for
steps that fail. Why: where a step's contact problems are hard, their cost
grows much faster than the step's length: in smaller steps the Newton iterations per unit time
hardly change while the sweeps fall, and the slow step comes before a far slower one. The
thresholds, judged per step on both counts, come from benchmarks/results/soft_mixture_steps.md
(figures also in benchmarks/results/design_figures.md).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from compute.errors import SimulationError, StepFailure
from compute.stepping.step_stats import StepStats, carrying, spent

GROW_AFTER = 16  # steps without a new cut before the depth goes down by one
SLOW_ITERATIONS = 10  # a step with more Newton iterations per accepted sub-step than this
SLOW_SWEEPS = 30  # and more contact-solve sweeps per iteration than this sends the next ones deeper
SLOW_DEPTH = 3  # the deepest level (h / 8) that slowness alone sends steps to


def slow(iterations: int, sweeps: int, sub_steps: int) -> bool:
    """Whether a step whose ``sub_steps`` accepted sub-steps took ``iterations`` Newton iterations
    and ``sweeps`` contact sweeps in all was slow (module docstring)."""
    return iterations > SLOW_ITERATIONS * sub_steps and sweeps > SLOW_SWEEPS * iterations


def step_with_cuts(attempt, state, h: float, max_cuts: int):
    """The state h after ``state`` (which is left as it was) and the step's report, by
    ``attempt(state, h, deepest) -> (State, StepReport)`` (which raises StepFailure carrying its
    work; ``deepest``: d = ``max_cuts``) in sub-steps h / 2**d, d from ``state.cut_depth``, one
    level deeper after each failing attempt (the rest of the step goes on at that depth); the
    next step starts one level deeper still if this one was slow. Raises SimulationError carrying
    the work of all attempts when an attempt fails at depth ``max_cuts``. The report is the last
    sub-step's, with the work (``work``, Newton iterations and sweeps) of all the step's
    attempts, failed ones included, its ``cuts`` (failed attempts), ``sub_steps`` (accepted
    ones), and the largest contact ``residual``, ``max_penetration`` and ``hold_torque`` of the
    accepted sub-steps (a penetration left at the start of an early sub-step is not hidden by a
    later one's)."""
    depth0 = depth = min(state.cut_depth, max_cuts)
    units, done, rep, cuts, sub_steps = 2**max_cuts, 0, None, 0, 0  # progress in units of h / 2**max_cuts
    work = accepted = StepStats()  # of all attempts, of the accepted sub-steps
    residual = penetration = torque = 0.0
    over = h  # the step length the impulses in the current state's memory are over
    current = state
    while done < units:
        current, over = _rescale_impulses(current, over, h / 2**depth), h / 2**depth
        try:
            current, rep = attempt(current, h / 2**depth, depth >= max_cuts)
        except StepFailure as exc:
            work += spent(exc)
            if depth >= max_cuts:
                cut = f"; the step failed down to sub-steps h / {2**depth} = {h / 2**depth:.4g} (h = {h:.4g})" if depth else ""
                raise carrying(SimulationError(f"step {state.step + 1}: {exc}{cut}"), work) from None
            work += StepStats(cuts=1)
            cuts += 1
            depth += 1
            continue  # from the state before the failed attempt (impulses over `over`)
        work += rep.work
        accepted += rep.work
        residual = float(np.maximum(residual, rep.residual))  # NaN stays
        penetration = max(penetration, rep.max_penetration)
        torque = max(torque, rep.hold_torque)
        done += units >> depth
        sub_steps += 1
    rep.cuts, rep.sub_steps, rep.residual, rep.max_penetration = cuts, sub_steps, residual, penetration
    rep.hold_torque = torque
    rep.work, rep.newton_iterations, rep.sweeps = work, work.newton_iterations, work.sweeps
    if slow(accepted.newton_iterations, accepted.sweeps, sub_steps) and depth < min(max_cuts - 1, SLOW_DEPTH):
        depth += 1
    depth_accepted = 0 if depth > depth0 else state.cut_accepted + 1
    if depth and depth_accepted >= GROW_AFTER:
        depth, depth_accepted = depth - 1, 0
    current = replace(_rescale_impulses(current, over, h),  # impulses of the last sub-step: to forces x h
                      time=state.time + h, step=state.step + 1, cut_depth=depth, cut_accepted=depth_accepted)
    if rep.h != h:
        rep.contacts.impulse *= h / rep.h
    return current, rep


def _rescale_impulses(state, over: float, to: float):
    """``state`` with its warm-start impulses rescaled from a step of length ``over`` to one of
    ``to`` (the same forces); ``state`` itself if they are equal."""
    if to == over:
        return state
    return replace(state, impulses={fam: a * (to / over) for fam, a in state.impulses.items()})
