"""What a body group fixes at the start of a step and hands back to the step's later calls.

``begin_step`` of every group returns one of these records; the stepper passes it back to the
group's step methods (free velocity, compliance, settling, ...). Why: the step's data (h, θ,
x_n, which bodies are settled, ...) is then visible where it is used, a failed attempt leaves
nothing behind in the group, and two attempts cannot mix their data.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class LinearStep:
    """A linear group's step (rigid disks, walls): its free velocity ``v_free`` and its 1x1
    compliance values ``inverse`` (1 / m̂, 0 for a body held at rest) on the global ``dofs``,
    all (k,). Exact after one contact solve: nothing changes during the step."""

    dofs: np.ndarray
    v_free: np.ndarray
    inverse: np.ndarray


@dataclass
class SoftStep:
    """A soft group's step (compute.bodies.soft): fixed at its start ``h``, ``theta``, positions
    ``x_n`` (B, n, 2), velocities ``v_n`` (B, 2n), element Jacobians ``j_n`` (compute.fem.batch.BodyBatch.jacobians)
    and the gravity load ``gravity`` (B, 2n) (M g); changed by the step's Newton iterations:
    ``iteration`` (free velocities evaluated so far), ``settled`` (B,) bodies whose correction
    fell below the tolerance, ``force`` (B,) bodies to refactorise at the next evaluation,
    ``stale`` (B,) bodies that kept an old factorisation at the last one, ``exact`` whether
    the next evaluation is a Newton one (SoftBodies.refresh), and ``v_free`` (B, 2n) the free
    velocity of the last evaluation of every body."""

    h: float
    theta: float
    x_n: np.ndarray
    v_n: np.ndarray
    j_n: np.ndarray
    gravity: np.ndarray
    v_free: np.ndarray
    settled: np.ndarray
    force: np.ndarray
    stale: np.ndarray
    exact: bool = False
    iteration: int = 0
