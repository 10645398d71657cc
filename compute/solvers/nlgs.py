"""Nonlinear Gauss–Seidel over contacts with the exact local 2D Signorini–Coulomb solution.

Unknowns: the contact impulses r_c = (r_n, r_t) over the step. For each contact the local
relative velocity at the end of the step is u_c = H_c^T v (v the generalised velocities,
updated in place as impulses change), and the normal condition is written on the predicted
end-of-step gap (Moreau–Jean with a gap term, no drift):

    g̃ + h θ u_n ≥ 0,  r_n ≥ 0,  (g̃ + h θ u_n) r_n = 0,     g̃ = g + h (1 - θ) u_n⁻,

i.e. Signorini on ũ_n = u_n + g̃ / (h θ); Coulomb on u_t: |r_t| ≤ μ r_n, sliding opposite u_t.
Stopping: the true error of the solution, the natural-map residual ‖f‖ / ‖r‖ of
:mod:`compute.contact.residual`, at most ``tol``. It is evaluated (one pass over the contacts,
no update) only after sweeps whose relative change sqrt(Σ|Δr|²) / sqrt(Σ|r|²) (LMGC90's quadratic
norm) is already below ``tol``: that change understates the error by about 1 / (1 - ρ) where the
sweeps contract by ρ close to 1, so alone it stops too early.

Stall detection (``stall_window`` > 0, for a caller with a fallback): every ``stall_window``
sweeps the error is evaluated, and the solve stops early, unconverged, when it is not below the
smallest error of the earlier checks (an iteration that oscillates), or, with ``projected_limit``
> 0, when the contraction of the last window, kept up, would need more than that many further
sweeps, or more than its budget has left, to reach the tolerance (an iteration too slow for the
caller's fallback to wait for, or that would miss). Where this happens: frictional point Gauss–Seidel in a compacting soft
mixture oscillates for thousands of sweeps on contacts of nearly singular soft corners (W_tt
much larger than W_nn, with strong n–t coupling), while without friction it converges
(benchmarks/results/design_figures.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from compute.contact.compliance import add_compliance, add_contact_impulse
from compute.contact.rows import generalised_impulse, local_velocity
from compute.solvers.report import SolveReport
from compute.contact.residual import Measure, contact_error


@dataclass(frozen=True)
class NLGS:
    """Nonlinear Gauss–Seidel: stops when the natural-map error of the impulses is below
    ``tolerance`` (module docstring), after ``max_sweeps``, or, with ``stall_window`` > 0, when it
    stalls; ``relaxation`` in (0, 1]."""

    tolerance: float
    max_sweeps: int
    relaxation: float = 1.0
    stall_window: int = 0
    measure: Measure = Measure()
    projected_limit: int = 0  # with stall_window: also stalled when the tolerance is this many sweeps away

    def solve(self, problem) -> SolveReport:
        """Solve ``problem`` (a ContactProblem) from its warm-start impulses, in place."""
        carr = problem.compliance.arrays()
        v_free = problem.free_velocity()
        v = v_free.copy()
        apply_impulses(problem.dof, problem.hn, problem.ht, problem.impulse, v, *carr)
        sweeps, residual = nlgs_solve(problem.dof, problem.hn, problem.ht, problem.W, problem.gap_term, problem.mu,
                                      problem.impulse, v, v_free, *carr, *self.measure.codes(problem, self.tolerance),
                                      self.max_sweeps, self.relaxation, self.stall_window, self.projected_limit)
        return SolveReport(problem.velocities(v), sweeps, residual)


@numba.njit(cache=True, inline="always")
def local_signorini_coulomb(wnn, wnt, wtn, wtt, bn, bt, mu):
    """Exact solution (r_n, r_t) of u = W r + b with Signorini on u_n and Coulomb on (r, u_t)."""
    if bn >= 0.0:
        return 0.0, 0.0  # separation: r = 0 is the solution
    if mu == 0.0:
        return -bn / wnn, 0.0
    det = wnn * wtt - wnt * wtn
    if det > 0.0:  # stick: u = 0
        rn = (-bn * wtt + bt * wnt) / det
        rt = (-bt * wnn + bn * wtn) / det
        if rn > 0.0 and abs(rt) <= mu * rn:
            return rn, rt
    for s in (1.0, -1.0):  # slide with u_t of sign s, r_t = -s mu r_n, u_n = 0
        den = wnn - s * mu * wnt
        if den <= 0.0:
            continue
        rn = -bn / den
        ut = (wtn - s * mu * wtt) * rn + bt
        if rn >= 0.0 and s * ut >= 0.0:
            return rn, -s * mu * rn
    return -bn / wnn, 0.0  # unreachable for a positive definite W; frictionless fallback


@numba.njit(cache=True, inline="always")
def stalled(error, best, tol, window, projected_limit, sweeps_left):
    """The stall test of an iteration whose error is checked every ``window`` sweeps (module
    docstring): ``error`` not below ``best``, the last check's (it oscillates), or, with
    ``projected_limit`` > 0, the contraction since that check, kept up, needing more than
    min(projected_limit, ``sweeps_left``) further sweeps to reach ``tol`` (converging, but too
    slowly for the caller)."""
    if error >= best:
        return True
    return projected_limit > 0 and best < np.inf and \
        np.log(tol / error) / np.log(error / best) * window > min(projected_limit, sweeps_left)


@numba.njit(cache=True)
def nlgs_solve(dof, hn, ht, W, gap_term, mu, r, v, v_free, diagonal, block, start, offset, values, kind, tol,
               bound, max_sweeps, relax, stall_window, projected_limit):
    """Solve the contact problem in place.

    dof, hn, ht (nc, m): rows of H over packed dofs; W (nc, 2, 2); gap_term (nc,) = g̃ / (h θ);
    mu (nc,); r (nc, 2) impulses (warm start in, solution out); v (n,) packed velocities that
    already include the warm-start impulses (v = v_free + M̂⁻¹ H r), ``v_free`` (n,); the
    compliance arrays of :meth:`compute.contact.compliance.Compliance.arrays`; the error measure
    (kind, tol, bound) of :meth:`compute.contact.residual.Measure.codes`. Returns (sweeps, error
    at the stop); stalled (module docstring) if the error is above tol before max_sweeps.
    """
    best = np.inf  # smallest error of the stall checks, the last one's while none has stalled
    for sweep in range(1, max_sweeps + 1):
        num = 0.0
        den = 0.0
        for c in range(dof.shape[0]):
            un, ut = local_velocity(dof, hn, ht, c, v)
            un += gap_term[c]
            rn0, rt0 = r[c, 0], r[c, 1]
            bn = un - W[c, 0, 0] * rn0 - W[c, 0, 1] * rt0
            bt = ut - W[c, 1, 0] * rn0 - W[c, 1, 1] * rt0
            rn, rt = local_signorini_coulomb(W[c, 0, 0], W[c, 0, 1], W[c, 1, 0], W[c, 1, 1], bn, bt, mu[c])
            rn = relax * rn + (1.0 - relax) * rn0
            rt = relax * rt + (1.0 - relax) * rt0
            dn, dt = rn - rn0, rt - rt0
            if dn != 0.0 or dt != 0.0:
                r[c, 0], r[c, 1] = rn, rt
                add_contact_impulse(v, c, dn, dt, dof, hn, ht, diagonal, block, start, offset, values)
            num += dn * dn + dt * dt
            den += rn * rn + rt * rt
        change = np.sqrt(num / den) if den > 0.0 else 0.0
        stall_check = stall_window > 0 and sweep % stall_window == 0 and sweep < max_sweeps
        if change <= tol or stall_check:
            error = contact_error(kind, tol, bound, dof, hn, ht, W, gap_term, mu, r, v, v_free)
            if change <= tol and error <= tol:
                return sweep, error
            if stall_check:
                if stalled(error, best, tol, stall_window, projected_limit, max_sweeps - sweep):
                    return sweep, error
                best = error
    return max_sweeps, contact_error(kind, tol, bound, dof, hn, ht, W, gap_term, mu, r, v, v_free)


@numba.njit(cache=True)
def apply_impulses(dof, hn, ht, r, v, diagonal, block, start, offset, values):
    """v += M̂⁻¹ H r (the warm start): H r gathered per dof first (contacts without impulse cost
    nothing), then each dense block's columns with an impulse added four at a time, each v[i]
    loaded and stored once for the four (column by column, a block's velocities were read and
    written once per column; figures in benchmarks/results/mprgp_product.md). The columns of a
    symmetric block are read as its rows: contiguous."""
    hr = generalised_impulse(dof, hn, ht, r, v.shape[0])
    for d in range(v.shape[0]):
        if block[d] < 0 and hr[d] != 0.0:
            v[d] += diagonal[d] * hr[d]
    cols = np.empty(0, np.int64)
    for b in range(start.size - 1):
        s0 = start[b]
        s = start[b + 1] - s0
        if cols.size < s:
            cols = np.empty(s, np.int64)
        k = 0
        for j in range(s):
            if hr[s0 + j] != 0.0:
                cols[k] = j
                k += 1
        i = 0
        while i < k:
            if i + 4 <= k:
                j0, j1, j2, j3 = cols[i], cols[i + 1], cols[i + 2], cols[i + 3]
                o0, o1, o2, o3 = offset[b] + j0 * s, offset[b] + j1 * s, offset[b] + j2 * s, offset[b] + j3 * s
                a0, a1, a2, a3 = hr[s0 + j0], hr[s0 + j1], hr[s0 + j2], hr[s0 + j3]
                for q in range(s):
                    v[s0 + q] += (values[o0 + q] * a0 + values[o1 + q] * a1) + (values[o2 + q] * a2 + values[o3 + q] * a3)
                i += 4
            else:
                add_compliance(v, s0 + cols[i], hr[s0 + cols[i]], diagonal, block, start, offset, values)
                i += 1


