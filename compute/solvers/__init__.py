"""Contact solvers: each takes a :class:`compute.contact.problem.ContactProblem` and returns the
end-of-step velocities, with the impulses written into ``problem.impulse``.

The interface is one method, ``solve(problem) -> SolveReport``; a solver knows nothing of body
kinds. Two implementations, chosen by the scene's ``solver.contact`` (:func:`for_scene`):

- ``"nlgs"``: :class:`~compute.solvers.nlgs.NLGS`, nonlinear Gauss–Seidel with the exact local 2D
  Signorini–Coulomb solution per contact;
- ``"block"``: :class:`~compute.solvers.block_gs.BlockGS`, the contacts of each soft body solved
  exactly together (semismooth Newton), Gauss–Seidel over bodies and single contacts;
- ``"auto"`` (default): ``block`` for a scene whose only moving bodies are one soft body and the
  walls, ``nlgs`` otherwise. Measured (single particle T6 x 92, 16 stages: the contact solve
  takes 0.20 s instead of 0.56 s; the point Gauss–Seidel contracts by only 0.96–0.985 per sweep
  there, the body's contacts being coupled through its compliance, while the block is one
  Newton solve). In a 144-disk mixture (κ = 0.5, μ = 0.2, T3 x 92) the blocks do not help:
  from the same cold start at P/E = 1 block Gauss–Seidel needs 8016 sweeps to 1e-6 against
  NLGS's 8136 (the slow coupling is between bodies, through the contact network), at 1.5–4
  times the cost per sweep; at P/E = 0.01, 49 against 53 sweeps to 1e-4. Without soft bodies
  every block is one contact and the two are the same iteration.

Both stop on the natural-map error of :mod:`compute.solvers.residual`.
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


def for_scene(settings, n_soft: int, n_rigid: int):
    """The contact solver of a scene's ``[solver]`` settings (module docstring), for a scene
    with ``n_soft`` soft bodies and ``n_rigid`` movable rigid disks."""
    from compute.solvers.block_gs import BlockGS
    from compute.solvers.nlgs import NLGS

    kind = settings.contact
    if kind == "auto":
        kind = "block" if n_soft == 1 and n_rigid == 0 else "nlgs"
    if kind == "block":
        return BlockGS(settings.nlgs_tolerance, settings.nlgs_max_sweeps)
    return NLGS(settings.nlgs_tolerance, settings.nlgs_max_sweeps, settings.relaxation)
