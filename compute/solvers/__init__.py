"""Contact solvers: each takes a :class:`compute.contact.problem.ContactProblem` and returns the
end-of-step velocities, with the impulses written into ``problem.impulse``.

The interface is one method, ``solve(problem) -> SolveReport``; a solver knows nothing of body
kinds. :class:`~compute.solvers.nlgs.NLGS` (nonlinear Gauss–Seidel with the exact local 2D
Signorini–Coulomb solution) is the implementation the scene's ``[solver]`` table configures.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class SolveReport:
    """``v`` (n_dofs,) velocities v_free + M̂⁻¹ H r on the dofs contacts touch (v_free elsewhere);
    ``iterations`` (sweeps for NLGS) and the solver's ``residual`` at its stop."""

    v: np.ndarray
    iterations: int
    residual: float
