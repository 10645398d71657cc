"""What a contact solve returns: the one type every solver and the Newton loop share, in a module
of its own so that the solver modules need not import their package's ``__init__`` (which picks
among them)."""

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
