r"""The Newton loop of a step with soft bodies (generalised Newton on the coupled problem, with
the contact rows H fixed at q_n but for the segment–disk rows the step gives, linearised again
at the end-of-step positions of the first iterate: compute.contact.end_of_step).

Iterations k = 0, 1, ... from v⁰ = v_free of the linear groups and v⁻ of the soft bodies:

    v_free = free velocity of every group at v^k          (soft: v^k - M̂⁻¹ R(v^k), batched)
    W = Hᵀ M̂⁻¹ H on the contact dofs                       (1x1 and dense compliance blocks)
    contact solve -> r, v on the contact dofs              (warm-started from the last iterate)
    v^{k+1} = v_free + M̂⁻¹ H r                             (soft: interior recovery)

until the iterate solves the step: either its last correction h θ |v^{k+1} - v^k|_∞ is at
most tol (a position correction), or, before the contact solve of iteration k >= 2, the pair
(v^k, r^k) of the current iterate and the last impulses has both true residuals small:

    h θ |M̂⁻¹ (R(v^k) - H r^k)|_∞ = h θ |v^k - v_free - M̂⁻¹ H r^k|_∞ <= tol     (impulse balance)
    error of (Hᵀ v^k, r^k) <= the contact solver's tolerance, in its measure   (Signorini–Coulomb)

The second test is what ends a step whose contact problem converges slowly: each contact solve
then stops after a sweep or two, on its own tolerance, and the velocities go on changing by
more than tol per iteration with the contact solver's progress alone, while the bodies are
already in balance with the impulses to well within tol. (For a settled body, below, v_free is
that of its last evaluation: its balance is then judged to first order, as its correction is.)
Devices that keep it robust:

- Anderson acceleration (depth ``ANDERSON``) of the fixed-point map v -> v^{k+1}: with a kept or
  a stabilised factorisation the iteration is a modified Newton, linearly convergent; mixing the
  last iterates (Walker & Ni 2011) restores fast convergence. Convergence is judged on the plain
  correction, never on an accelerated one. The mixing history is dropped whenever the plain
  correction grew: the map then changed under the iterates (contacts switching between stick,
  slip and open, bodies refactorising), and mixing with iterates of the old map drove such
  steps into hundreds of iterations and cuts.
- A contact solve that ends above its tolerance (sweep limit, stall) is a miss; the second miss
  of a step fails it (the step control cuts it, and smaller steps pose easier contact
  problems), rather than paying the sweep limit at every further iteration (a mixture step
  spent most of its time in such solves before its cut). At the deepest cut (``misses_fail``
  false) a miss no longer fails the step: the iteration goes on, and a step that converges with
  its last contact solve above tolerance is kept and reported with that residual (the run then
  ends INCOMPLETE, compute.summary). Why: a large T6 mixture at P/E = 1 stopped on solves
  ending just above their tolerance after the sweep limit, at every depth of the step control
  (figures in benchmarks/results/design_figures.md).
- Backtracking: an update that would change some element's area by more than a factor
  1 / ``JACOBIAN_RATIO`` in one step is halved until it does not.
- A correction that contracted by less than ``SLOW_CONTRACTION`` makes the bodies that kept an
  old factorisation refactorise; bodies whose own correction is below tol are settled (not
  reassembled nor refactorised in the next iterations of the step).

Failures raise :class:`compute.errors.StepFailure` (the step control cuts the step).
"""

from __future__ import annotations

import numpy as np

from compute.contact.compliance import Compliance
from compute.contact.problem import ContactProblem
from compute.errors import StepFailure
from compute.fixed_order import least_squares
from compute.solvers.report import SolveReport
from compute.stepping.step_stats import StepStats, carrying
from compute.timing import TIMES

ANDERSON = 4
RELINEARISED_AT = 2  # the iteration whose iterate the segment–disk rows are linearised at (end_rows)
CONTACT_MISSES = 2  # contact solves above tolerance that fail a step
JACOBIAN_RATIO = 0.5
MAX_BACKTRACKS = 12
SLOW_CONTRACTION = 0.25


def solve_step(step, contacts, v_minus, solver, tol: float, max_iterations: int, misses_fail: bool = True,
               end_rows=None):
    """End-of-step velocities (n_dofs,), the last solve report and the attempt's work
    (StepStats), for the groups of ``step`` (a GroupStep, compute.stepping.groups).
    ``contacts`` holds the warm start and receives the impulses. ``misses_fail``: whether the
    CONTACT_MISSES-th contact solve above tolerance fails the step (module docstring).
    ``end_rows``: rows of ``contacts`` linearised again at the end-of-step positions of the
    iterate of iteration RELINEARISED_AT (compute.contact.end_of_step.EndOfStepSegmentRows), or
    None. A StepFailure carries the work
    spent (StepStats, its ``work``)."""
    its = sweeps = backtracks = 0
    try:
        n, h, theta = step.n_dofs, step.h, step.theta
        soft_dofs = step.contact_dofs(contacts)
        v = step.initial_velocity(v_minus)
        v_free = np.zeros(n)
        history: list = []
        err_prev = np.inf
        misses = 0
        kept = None  # (problem, the factorisations its compliance blocks were made with)
        y, y_stamp = None, None  # M̂⁻¹ H r of the last impulses, and the factorisations it was made with
        for it in range(1, max_iterations + 1):
            its += 1  # every iteration, those of failing attempts too
            with TIMES("free velocity"):
                step.free_velocity(v, v_free)
            kept = contact_problem(step, contacts, soft_dofs, v_free, v_minus, kept)
            problem, stamp = kept
            relinearise_at(it, end_rows, contacts, problem, v)
            if it > 1:
                with TIMES("residuals"):
                    if y_stamp != stamp:  # some body refactorised since y = M̂⁻¹ H r was computed
                        y, y_stamp = step.compliance_times(problem.generalised_impulse(n)), stamp
                    balance = h * theta * float(np.max(np.abs(v - v_free - y)))
                    if balance <= tol:
                        contact = solver.measure.error(problem, solver.tolerance, v)
                        if contact <= solver.tolerance:
                            report = SolveReport(v, report.iterations, contact)
                            break
            with TIMES("contact solve"):
                report = solver.solve(problem)
            sweeps += report.iterations
            if step.iterates and not report.residual <= solver.tolerance:
                misses += 1
                if misses_fail and misses == CONTACT_MISSES:
                    raise StepFailure(f"the contact solve missed its tolerance {solver.tolerance:.3g} {misses} times "
                                      f"(natural-map error {report.residual:.3g} after {report.iterations} sweeps, "
                                      f"Newton iteration {it})")
            v_new = report.v
            with TIMES("recovery"):  # soft bodies: v_b = v_free,b + M̂_b⁻¹ (H r)_b on all their dofs
                y, y_stamp = step.compliance_times(problem.generalised_impulse(n)), stamp
                step.recover(v_new, v_free, y)
            if not np.all(np.isfinite(v_new)):
                raise StepFailure(f"non-finite velocities at Newton iteration {it}")
            err = h * theta * float(np.max(np.abs(v_new - v))) if n else 0.0
            last = (v, v_new)
            if err <= tol:
                v, damped = _admissible(step, v, v_new)
                backtracks += damped
                break
            step.settle(v, v_new, tol)
            if ANDERSON:
                if err > err_prev:
                    history.clear()
                v_new = _anderson(history, v, v_new)
            v, damped = _admissible(step, v, v_new)
            backtracks += damped
            if it > 1 and err > 1e6 * max(err_prev, tol):
                raise StepFailure(f"Newton diverges (position correction {err:.3g} after {err_prev:.3g}, iteration {it})")
            if err > SLOW_CONTRACTION * err_prev:
                step.contraction_was_slow()
            err_prev = err
        else:
            raise StepFailure(f"Newton did not converge in {max_iterations} iterations "
                              f"(last position correction {err:.3g}, tolerance {tol:.3g}{_slowest(step, *last, tol)})")
    except StepFailure as exc:
        carrying(exc, StepStats(its, sweeps, backtracks))
        raise
    return v, report, StepStats(its, sweeps, backtracks)


def relinearise_at(it: int, end_rows, contacts, problem, v: np.ndarray) -> None:
    """At iteration RELINEARISED_AT, the rows ``end_rows`` (or None) of ``contacts`` and
    ``problem`` made again at the end-of-step positions of the iterate ``v`` (n_dofs,)."""
    if end_rows is not None and it == RELINEARISED_AT:
        end_rows.relinearise(contacts, problem, v)


def contact_problem(step, contacts, soft_dofs: list, v_free: np.ndarray, v_minus: np.ndarray, kept):
    """(problem, stamp): the step's ContactProblem on the free velocity ``v_free`` (n_dofs,,
    filled in place by the iterations, which the problem reads) and the factorisation stamp its
    compliance blocks were made with. ``kept`` (problem, stamp) of the last iteration, or None,
    is returned as it is while no body has refactorised since (compliance blocks unchanged).
    ``soft_dofs`` the nonlinear groups' contact dofs (GroupStep.contact_dofs)."""
    stamp = step.factorisation_stamp()
    if kept is not None and kept[1] == stamp:
        return kept
    with TIMES("compliance"):
        dense = [g.compliance(st, d) for g, st, d in soft_dofs if len(d)]
        comp = Compliance.build(step.n_dofs, step.diagonals(), dense)
        return ContactProblem.build(contacts, comp, v_free, v_minus, step.h, step.theta), stamp


def _slowest(step, v, v_new, tol: float, shown: int = 5) -> str:
    """'; above it in body 3 (2.1e-07), ...': the soft bodies whose last correction exceeded
    ``tol``, largest first (at most ``shown``); '' if none did."""
    ids, c = step.corrections(v, v_new)
    over = np.flatnonzero(c > tol)
    if not over.size:
        return ""
    top = over[np.argsort(c[over])[::-1][:shown]]
    more = f" and {over.size - shown} more" if over.size > shown else ""
    return "; above it in " + ", ".join(f"body {ids[i]} ({c[i]:.2g})" for i in top) + more


def _anderson(history: list, v: np.ndarray, g: np.ndarray) -> np.ndarray:
    """Anderson acceleration of the fixed-point map v -> g = G(v) (depth ANDERSON)."""
    history.append((v.copy(), g.copy()))
    if len(history) > ANDERSON + 1:
        history.pop(0)
    if len(history) < 2:
        return g
    f = np.array([gi - vi for vi, gi in history])  # (m + 1, n) residuals
    dg = np.diff(np.array([gi for _, gi in history]), axis=0)  # (m, n)
    coef = least_squares(np.diff(f, axis=0), f[-1], 1e-10)  # fixed-order sums (compute.fixed_order)
    out = g.copy()
    for c, d in zip(coef, dg):
        out -= c * d
    return out if np.all(np.isfinite(out)) else g


def _admissible(step, v: np.ndarray, v_new: np.ndarray) -> tuple[np.ndarray, bool]:
    """(v + a (v_new - v), whether a < 1) for the first a = 1, 1/2, 1/4, ... with which every
    element of every soft body keeps J / J_n within [JACOBIAN_RATIO, 1 / JACOBIAN_RATIO] (a
    Newton step from a linearised contact solution may overshoot a large load increment; no
    element really changes its area that much in one step). Raises StepFailure if none is found."""
    a = 1.0
    with TIMES("backtracking check"):
        for _ in range(MAX_BACKTRACKS):
            trial = v + a * (v_new - v) if a < 1.0 else v_new
            bad = area_violation(step, trial)
            if bad is None:
                return trial, a < 1.0
            a *= 0.5
    body, els, r = bad
    raise StepFailure(f"body {body}: {els.size} element(s) {els[:10].tolist()} would change their area by more "
                      f"than a factor {1.0 / JACOBIAN_RATIO:g} in one step (J/J_n down to {r:.3g}) even after "
                      f"{MAX_BACKTRACKS} backtracking halvings of the Newton update (h = {step.h:.4g})")


def area_violation(step, v: np.ndarray):
    """None if every element of every soft body keeps J / J_n within [JACOBIAN_RATIO,
    1 / JACOBIAN_RATIO] with velocities v (n_dofs,); else (body id, elements, smallest ratio) of
    the first body that does not (SoftBodies.area_change)."""
    return step.area_violation(v, JACOBIAN_RATIO, 1.0 / JACOBIAN_RATIO)
