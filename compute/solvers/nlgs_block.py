"""NLGS first, block Gauss–Seidel where NLGS stalls: the contact solver of soft mixtures.

Point Gauss–Seidel (:mod:`compute.solvers.nlgs`) is the cheaper sweep (2–4 times cheaper than a
block sweep) and carries a load through a contact network as fast as block Gauss–Seidel does
(the slow coupling there is between bodies). But in a compacting soft mixture its frictional
iteration can stall at an error of 1e-3–1e-2 (its stall detection); block Gauss–Seidel
(:mod:`compute.solvers.block_gs`), which solves the contacts of each soft body together, then
takes over from the NLGS iterate and converges where NLGS stalled
(benchmarks/results/design_figures.md).
"""

from __future__ import annotations

from dataclasses import dataclass

from compute.solvers import SolveReport
from compute.solvers.block_gs import BlockGS
from compute.solvers.nlgs import NLGS

STALL_WINDOW = 50  # sweeps between NLGS's stall checks


@dataclass(frozen=True)
class NLGSThenBlock:
    """NLGS with stall detection, then block Gauss–Seidel for the remaining sweeps; stops on the
    natural-map error at most ``tolerance`` or after ``max_sweeps`` sweeps of both together."""

    tolerance: float
    max_sweeps: int
    relaxation: float = 1.0

    def solve(self, problem) -> SolveReport:
        """Solve ``problem`` (a ContactProblem) from its warm-start impulses, in place."""
        first = NLGS(self.tolerance, self.max_sweeps, self.relaxation, STALL_WINDOW).solve(problem)
        if first.residual <= self.tolerance or first.iterations >= self.max_sweeps:
            return first
        then = BlockGS(self.tolerance, self.max_sweeps - first.iterations).solve(problem)
        return SolveReport(then.v, first.iterations + then.iterations, then.residual)
