"""NLGS first, a stronger solver where NLGS stalls: the contact solvers of packings.

Point Gauss–Seidel (:mod:`compute.solvers.nlgs`) has the cheapest iteration and, warm-started
from the last solve, usually converges in a few sweeps. Where it does not, something stronger
takes over from its iterate:

- block Gauss–Seidel (:mod:`compute.solvers.block_gs`, ``nlgs_block``): in a compacting soft
  mixture NLGS's frictional iteration can oscillate at an error of 1e-3–1e-2 on contacts of
  nearly singular soft corners, where block Gauss–Seidel, which solves the contacts of each soft
  body together, converges (benchmarks/results/design_figures.md);
- the interior point (:mod:`compute.solvers.interior_point`, ``nlgs_ip``): in a large or
  stiff packing NLGS converges, but at a rate that needs thousands of sweeps, while the interior
  point's iterations do not grow with the packing (benchmarks/results/contact_problems.md). NLGS
  hands over when its last ``STALL_WINDOW`` sweeps, kept up, would need more than
  ``PROJECTED_SWEEPS`` further sweeps; the interior point's cold start then costs about as much
  as that many sweeps on the packings measured.

The answer kept is the one with the smaller error: the fallback may do worse than NLGS's iterate
(the interior point on a jammed frictional rigid packing). Where the interior point misses, NLGS
goes on from the better iterate for the rest of its sweeps (``resume``): it had stopped only for
being slow, and slow is still better than stopped.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from compute.solvers import SolveReport
from compute.solvers.block_gs import BlockGS
from compute.solvers.interior_point import InteriorPoint
from compute.solvers.nlgs import NLGS
from compute.solvers.residual import Measure

STALL_WINDOW = 50  # sweeps between NLGS's stall checks
PROJECTED_SWEEPS = 1000  # nlgs_ip: NLGS hands over when the tolerance is projected further away than this
FALLBACK_IP_ITERATIONS = 40  # nlgs_ip: where the interior point converges it needs 12-22 iterations


@dataclass(frozen=True)
class NLGSThen:
    """``first`` (an NLGS with stall detection), then ``then`` from its iterate if it stalled;
    each has its own iteration budget. Stops on ``first``'s tolerance and measure."""

    first: NLGS
    then: object
    resume: bool = False  # NLGS goes on (without stall detection) from the better iterate if ``then`` misses

    @property
    def tolerance(self) -> float:
        return self.first.tolerance

    @property
    def measure(self) -> Measure:
        return self.first.measure

    @classmethod
    def block(cls, tolerance: float, max_sweeps: int, relaxation: float = 1.0, measure: Measure = Measure()):
        """``nlgs_block``: NLGS until it oscillates, then block Gauss–Seidel."""
        return cls(NLGS(tolerance, max_sweeps, relaxation, STALL_WINDOW, measure),
                   BlockGS(tolerance, max_sweeps, measure))

    @classmethod
    def interior_point(cls, tolerance: float, max_sweeps: int, relaxation: float = 1.0,
                       measure: Measure = Measure()):
        """``nlgs_ip``: NLGS until it oscillates or is projected too slow, then the interior point,
        then NLGS again if that missed."""
        return cls(NLGS(tolerance, max_sweeps, relaxation, STALL_WINDOW, measure, PROJECTED_SWEEPS),
                   InteriorPoint(tolerance, FALLBACK_IP_ITERATIONS, measure), resume=True)

    def solve(self, problem) -> SolveReport:
        """Solve ``problem`` (a ContactProblem) from its warm-start impulses, in place."""
        first = self.first.solve(problem)
        if first.residual <= self.tolerance or first.iterations >= self.first.max_sweeps:
            return first
        kept = problem.impulse.copy()
        then = self.then.solve(problem)
        iterations = first.iterations + then.iterations
        best = then
        if then.residual > first.residual:
            problem.impulse[:] = kept
            best = first
        if self.resume and best.residual > self.tolerance:
            rest = replace(self.first, max_sweeps=self.first.max_sweeps - first.iterations, stall_window=0)
            best = rest.solve(problem)
            iterations += best.iterations
        return SolveReport(best.v, iterations, best.residual)
