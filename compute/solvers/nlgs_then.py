"""NLGS first, a stronger solver where NLGS stalls: the contact solvers of packings.

Point Gauss–Seidel (:mod:`compute.solvers.nlgs`) has the cheapest iteration and, warm-started
from the last solve, usually converges in a few sweeps. Where it does not, something stronger
takes over from its iterate:

- block Gauss–Seidel (:mod:`compute.solvers.block_gs`, ``nlgs_block``): in a compacting soft
  mixture NLGS's frictional iteration can oscillate at an error of 1e-3–1e-2 on contacts of
  nearly singular soft corners, where block Gauss–Seidel, which solves the contacts of each soft
  body together, converges (benchmarks/results/design_figures.md); where it does not either, it
  stops when its own error stalls (:mod:`compute.solvers.block_gs`), and the solve is a miss;
- an interior point (``nlgs_ip``): in a large or stiff packing NLGS converges, but at a rate
  that needs tens of thousands of sweeps, while an interior point's iterations do not grow with
  the packing. NLGS hands over when its last ``STALL_WINDOW`` sweeps, kept up, would not reach
  the tolerance within its budget, so that the fallback is paid only where NLGS would miss: its
  sparse factorisations cost the more sweeps the larger the packing, so no fixed threshold in
  sweeps suits every packing. With soft bodies the fallback is
  the Stewart–Trinkle interior point (:mod:`compute.solvers.interior_point`); without, that one
  and then the cone fixed point (:mod:`compute.solvers.cone_point`): the first settles most
  solves of a packing on its way to jamming, the second converges on the jammed ones, where the
  first stalls. Each starts cold: the cone fixed point's first shift from a stalled NLGS iterate
  was a worse start than zero impulses.

The answer kept is the one with the smallest error: a fallback may do worse than NLGS's iterate.
Where every fallback misses, NLGS goes on from the best iterate for the rest of its sweeps
(``resume``): it had stopped only for being slow, and slow is still better than stopped. Figures
for all of this: benchmarks/results/contact_problems.md.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from compute.solvers.report import SolveReport
from compute.solvers.block_gs import BlockGS
from compute.solvers.cone_point import ConePoint
from compute.solvers.interior_point import InteriorPoint
from compute.solvers.nlgs import NLGS
from compute.contact.residual import Measure

STALL_WINDOW = 50  # sweeps between NLGS's stall checks
BLOCK_STALL_WINDOW = 10  # nlgs_block: sweeps between the block fallback's stall checks
BLOCK_PROJECTED_SWEEPS = 100  # and the most further sweeps it may be projected to need
FALLBACK_IP_ITERATIONS = 40  # nlgs_ip: about twice what the interior point needs where it converges
FALLBACK_CONE_ITERATIONS = 150  # and the cone fixed point (contact_problems.md)


@dataclass(frozen=True)
class NLGSThen:
    """``first`` (an NLGS with stall detection), then, if it stalled, the ``fallbacks`` in turn
    until one reaches the tolerance, each from NLGS's iterate or, ``cold``, from zero impulses,
    with its own iteration budget. Stops on ``first``'s tolerance and measure."""

    first: NLGS
    fallbacks: tuple
    resume: bool = False  # NLGS goes on (without stall detection) from the best iterate if every fallback misses
    cold: bool = False  # the fallbacks start from zero impulses, not from NLGS's iterate

    @property
    def tolerance(self) -> float:
        return self.first.tolerance

    @property
    def measure(self) -> Measure:
        return self.first.measure

    @classmethod
    def block(cls, tolerance: float, max_sweeps: int, relaxation: float = 1.0, measure: Measure = Measure()):
        """``nlgs_block``: NLGS until it oscillates, then block Gauss–Seidel until it converges
        or stalls in its turn (compute.solvers.block_gs; a block sweep costs many point sweeps)."""
        return cls(NLGS(tolerance, max_sweeps, relaxation, STALL_WINDOW, measure),
                   (BlockGS(tolerance, max_sweeps, measure, BLOCK_STALL_WINDOW, BLOCK_PROJECTED_SWEEPS),))

    @classmethod
    def interior_point(cls, tolerance: float, max_sweeps: int, relaxation: float = 1.0,
                       measure: Measure = Measure(), soft: bool = True):
        """``nlgs_ip``: NLGS until it oscillates or is projected too slow, then an interior point
        (the Stewart–Trinkle one, without ``soft`` bodies then the cone fixed point), then NLGS
        again if they missed."""
        fallbacks = (InteriorPoint(tolerance, FALLBACK_IP_ITERATIONS, measure),)
        if not soft:
            fallbacks += (ConePoint(tolerance, FALLBACK_CONE_ITERATIONS, measure),)
        return cls(NLGS(tolerance, max_sweeps, relaxation, STALL_WINDOW, measure, max_sweeps), fallbacks,
                   resume=True, cold=True)

    def solve(self, problem) -> SolveReport:
        """Solve ``problem`` (a ContactProblem) from its warm-start impulses, in place."""
        first = self.first.solve(problem)
        if first.residual <= self.tolerance or first.iterations >= self.first.max_sweeps:
            return first
        best, kept, iterations = first, problem.impulse.copy(), first.iterations
        for fallback in self.fallbacks:
            if self.cold:
                problem.impulse[:] = 0.0
            then = fallback.solve(problem)
            iterations += then.iterations
            if then.residual <= best.residual:
                best, kept = then, problem.impulse.copy()
            if best.residual <= self.tolerance:
                break
        problem.impulse[:] = kept
        if self.resume and best.residual > self.tolerance:
            rest = replace(self.first, max_sweeps=self.first.max_sweeps - first.iterations, stall_window=0)
            best = rest.solve(problem)
            iterations += best.iterations
        return SolveReport(best.v, iterations, best.residual)
