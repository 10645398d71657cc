"""The stall rule: a pressure stage that makes no progress stops the run early, INCOMPLETE.

A step of a stage makes progress when the stage's load is still being ramped
(compute.stepping.load_control), or its contact error (the natural-map error, history column
``nlgs_residual``) is below half the smallest since the last progress, or φ or the box area
differs by more than ``loading.phi_tolerance`` (relative) from their values at the last
progress. A stage is stalled after ``loading.stall_steps`` steps without progress (0: never)
whose last contact solve ended above ``solver.contact_tolerance``: the run writes the stage's frame
(not equilibrated) and ends INCOMPLETE, the diagnosis naming the stage, the contact error and
the settings to change. (A stage whose contact solves meet their tolerance is not stalled
whatever its packing does: its contact error is not what keeps it from ending.)

Why: a stage whose contact solves cannot reach their tolerance (too few sweeps for the time
step) and whose packing no longer compacts never passes the stage-end test (compute.run); it
ran on to ``max_steps_per_stage`` (200 000 steps by default; benchmarks/results/design_figures.md
has a small rigid scene that did) to end INCOMPLETE all the same.

The rule's memory is part of the state (``State.stall_*``), so a resumed run stalls where the
uninterrupted one does.
"""

from __future__ import annotations

import math

HALVING = 0.5  # a contact error is progress when below this fraction of the stage's smallest


def start_stage(state) -> None:
    """Forget the previous stage's progress."""
    state.stall_residual, state.stall_phi, state.stall_area, state.stall_mark = math.inf, math.nan, math.nan, 0


def record(state, residual: float, phi: float, area: float, ramped: bool, scene) -> None:
    """After a step of the stage (``state.stage_steps`` counts it): note whether it made
    progress (module docstring). ``area``: the box area; ``ramped``: the stage's load is fully
    applied."""
    moves = scene.loading.phi_tolerance
    moved = not (abs(phi - state.stall_phi) <= moves * state.stall_phi
                 and abs(area - state.stall_area) <= moves * state.stall_area)  # NaN at the start: moved
    if not ramped or residual < HALVING * state.stall_residual or moved:
        state.stall_mark = state.stage_steps
        state.stall_residual, state.stall_phi, state.stall_area = residual, phi, area
    else:
        state.stall_residual = min(state.stall_residual, residual)


def stalled(state, scene, residual: float) -> bool:
    """The stage went ``loading.stall_steps`` steps without progress (never when it is 0) and its
    last contact error ``residual`` is above the tolerance."""
    steps = scene.loading.stall_steps
    return steps > 0 and state.stage_steps - state.stall_mark >= steps and residual > scene.solver.contact_tolerance


def diagnosis(state, scene, pressure: float, residual: float) -> str:
    """One line: the stage, its contact error and what to change."""
    s, ld = scene.solver, scene.loading
    return (f"stage {state.stage} (P = {pressure:.4g}) stalled at step {state.step}: for {ld.stall_steps} steps "
            f"(loading.stall_steps) phi and the walls moved by less than loading.phi_tolerance = {ld.phi_tolerance:g} "
            f"and the contact error did not halve (smallest {state.stall_residual:.3g}, last {residual:.3g} "
            f"> solver.contact_tolerance = {s.contact_tolerance:g}); the contact solver stops at solver.nlgs_max_sweeps "
            f"= {s.nlgs_max_sweeps}: raise it, or lower solver.time_step = {s.time_step:g}")
