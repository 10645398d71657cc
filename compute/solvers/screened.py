r"""Contact solves on the contacts that can close, around any contact solver (constraint generation).

Most rows of a packing's contact problem are candidates of the Verlet skin that stay open over
the step. A contact left out with r = 0 satisfies the contact law exactly where its normal
velocity ũ_n = u_n + g̃ / (h θ) is not negative at the solution: the natural map of
:mod:`compute.contact.residual` vanishes there (r − P_K(r − ρ ū) = −P_K(−ρ ū) = 0, for any μ,
as ū_n ≥ ũ_n ≥ 0), so leaving it out changes no solution. Hence:

1. solve the problem restricted to the contacts that hold an impulse (the warm start) or whose
   normal velocity under the free motion, ũ_n(v_free), is below ``margin`` times the fastest
   approach of any contact, −min ũ_n(v_free);
2. at the solution's velocities, the contacts left out that close (ũ_n < 0) join, with those
   left out within the same margin, and the restricted problem is solved again, warm-started
   from its impulses; until none closes.

The impulses are then the whole problem's solution, and its error, in every measure, is the
restricted problem's or less (the left-out contacts add no error, and to the velocity measures'
denominators only). Why: a solve's products cost in proportion to the rows, and MPRGP's dense
block of a soft body (:mod:`compute.contact.delassus`) in proportion to their square, while in
a compressed soft packing most rows are open (figures: benchmarks/results/screened_rows.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from compute.solvers.report import SolveReport


@dataclass(frozen=True)
class Screened:
    """``inner`` (any contact solver) on the contacts that can close (module docstring), those
    within ``margin`` (> 0) times the fastest free approach; its tolerance and measure are the
    inner solver's."""

    inner: object
    margin: float

    @property
    def tolerance(self) -> float:
        return self.inner.tolerance

    @property
    def measure(self):
        return self.inner.measure

    def solve(self, problem) -> SolveReport:
        """Solve ``problem`` in place (impulses of the contacts left out set to 0); the report's
        iterations are the inner solver's over every round."""
        u = problem.normal_velocity(problem.v_free)
        band = self.margin * max(-float(u.min()), 0.0) if len(problem) else 0.0
        keep = (u < band) | (problem.impulse[:, 0] > 0.0)
        iterations = 0
        while True:
            rows = np.flatnonzero(keep)
            part = problem.restricted(rows)
            report = self.inner.solve(part)
            iterations += report.iterations
            problem.impulse[:] = 0.0
            problem.impulse[rows] = part.impulse
            u = problem.normal_velocity(report.v)
            if not np.any(~keep & (u < 0.0)):
                return SolveReport(report.v, iterations, report.residual)
            keep |= u < band
