"""What the stepper asks of a body group: a linear group (its free velocity exact after one
contact solve, a 1x1 compliance per dof) or a nonlinear one (Newton iterations within a step,
dense compliance blocks per body).

compute.stepping talks to body groups only through these protocols (compute.stepping.groups),
so that a new kind of body is a new group satisfying one of them, and nothing in stepping/
changes (tests/compute/test_protocols.py checks both sides). Arrays: q, v, out (n_dofs,) the
model's generalised coordinates and velocities; ``dofs`` the group's slice of them.
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

import numpy as np

from compute.bodies.load import Load
from compute.bodies.step_records import LinearStep, SoftStep


@runtime_checkable
class LinearGroup(Protocol):
    """Rigid disks, walls: ``begin_step`` gives the step's free velocity and compliance."""

    kind: str
    nonlinear: bool
    dofs: slice

    def __len__(self) -> int: ...

    def begin_step(self, q: np.ndarray, v: np.ndarray, h: float, theta: float, load: Load) -> LinearStep: ...


@runtime_checkable
class NonlinearGroup(Protocol):
    """Soft bodies: a step is Newton iterations on the record ``begin_step`` returns (the
    methods taking ``step``); the factorisations of M̂ are kept by the group between steps."""

    kind: str
    nonlinear: bool
    dofs: slice
    ids: np.ndarray
    hold_rotation: bool

    def __len__(self) -> int: ...

    def begin_step(self, q: np.ndarray, v: np.ndarray, h: float, theta: float, load: Load) -> SoftStep: ...

    def free_velocity(self, step: SoftStep, v: np.ndarray, out: np.ndarray) -> None: ...

    def refresh(self, step: SoftStep) -> None: ...

    def settle(self, step: SoftStep, v_old: np.ndarray, v_new: np.ndarray, tol: float) -> None: ...

    def corrections(self, step: SoftStep, v_old: np.ndarray, v_new: np.ndarray) -> np.ndarray: ...

    def contraction_was_slow(self, step: SoftStep) -> None: ...

    def compliance(self, step: SoftStep, dofs: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]: ...

    def compliance_times(self, hr: np.ndarray) -> np.ndarray: ...

    def area_change(self, step: SoftStep, v: np.ndarray, lo: float, hi: float) -> Any: ...

    def momentum_residual(self, step: SoftStep, v: np.ndarray) -> np.ndarray: ...

    def hold_torques(self, step: SoftStep, v: np.ndarray, hr: np.ndarray) -> np.ndarray: ...

    def held_directions(self) -> np.ndarray | None: ...

    def use_indefinite(self, on: bool) -> None: ...

    def expected_negative(self) -> int: ...

    def factorisation_stamp(self) -> int: ...

    def factorisation_counts(self) -> tuple[int, int]: ...

    def forget_factorisations(self) -> None: ...
