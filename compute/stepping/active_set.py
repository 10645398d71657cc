r"""The step of one soft body alone with the walls, frictionless, its rotation held: a semismooth
Newton on the step's coupled problem (a primal–dual active-set method), the contact conditions
linearised inside the iteration instead of solved to convergence at every iterate as in
:mod:`compute.stepping.newton`.

With G the body's compliance bordered by the held rotation (compute.bodies.soft_matrix), per
iteration k from v⁰ (v⁻ on the body, the free velocity of the walls) and the warm-start
impulses r⁰:

    v_free = v^k − G R(v^k) − z (cᵀ v^k) / s      (the exact Newton step without contact)
    ũ = Hᵀ v^k + g̃ / (hθ)                          (normal velocities of the current iterate)
    A = {i : r_i > 0} at k = 0 (the warm start's contacts), then {i : r_i − ũ_i / |W_ii| > 0}
    W_AA r̂_A = −(Hᵀ v_free + g̃ / (hθ))_A,  r̂ = 0 off A
    v̂ = v_free + M̂⁻¹ H r̂                           (G on the body)
    (v^{k+1}, r^{k+1}) = (v^k, r^k) + a (v̂ − v^k, r̂ − r^k)

The third line is the KKT system [M̂ −c −H_A; cᵀ 0 0; H_Aᵀ 0 0] by its Schur complement on
the contact rows; the tangent is assembled at every iteration and refactorised where it changed
by more than 1e-3 (SoftBodies.refresh).
a = 1, 1/2, ... the first step that keeps every element's area change within the safeguard of
compute.stepping.newton and decreases the merit (Armijo)

    |P (F(v) − H r)|² + |min(r, ũ / |W_ii|)|² + Σ_b (c_bᵀ v_b)² / c_bᵀ c_b,

F the momentum residual of every group (soft: R_b of compute.bodies.soft; walls: m̂ (v − v_free)),
P the projection off each held direction c_b (the hold's multiplier takes that part). The Newton
direction descends on it wherever the active set holds; without it, the first iterations of a
load stage's first step carry the pressed body into ever more unstable states (negative pivots
2 → 57) and never settle. It ends when hθ |v^{k+1} − v^k|_∞ ≤ tol, the impulses are
non-negative, the open contacts open (ũ ≥ −tol / (hθ)) and the natural-map error is below the
contact tolerance.

The exact M̂ is kept where it is indefinite (NewtonMatrices.set_indefinite): a pressed body's
boundary nodes wrinkle in modes its active contacts hold. The step is accepted only if M̂ is
positive definite on the velocities the active contacts and the hold leave free: the active
block W_AA then has exactly ``expected_negative`` negative eigenvalues (Haynsworth's inertia
theorem on the KKT matrix). A step that fails that check, stalls (``SHORT_STEPS`` steps in a
row shorter than ``SHORT_STEP``) or does not converge in ``ITERATIONS`` is taken again by the
fixed-point loop of :mod:`compute.stepping.newton` with positive definite matrices (counted as
``fallbacks``).

Why: the fixed-point loop needs a positive definite M̂ for its contact solver, so a pressed
body iterates with a stabilised matrix, a modified Newton that converges linearly; here the
iteration is Newton's, a few iterations per step once a stage has started (single particle,
benchmarks/results/active_set_single_particle.md). Where it stalls: a mean-dilatation T6 disk
that fills its box at P/E = 1, whose M̂ has many more and far larger negative eigenvalues there
than the standard T6 disk on the same mesh, mostly on the nodes against the walls; the line
search then cuts its steps short (benchmarks/results/single_particle_stages.md; figures in
benchmarks/results/design_figures.md).
"""

from __future__ import annotations

import numpy as np

from compute.errors import StepFailure
from compute.solvers.report import SolveReport
from compute.stepping import newton
from compute.stepping.step_stats import StepStats, carrying, spent
from compute.timing import TIMES

ITERATIONS = 20  # of one attempt before the fixed-point loop takes over
SHORT_STEP, SHORT_STEPS = 0.25, 3  # that many consecutive steps shorter than that: stalled, taken over


def solve_step(step, contacts, v_minus, solver, tol: float, max_iterations: int, misses_fail: bool = True,
               end_rows=None):
    """End-of-step velocities, solve report and the attempt's work, as newton.solve_step (same
    arguments): by the active-set Newton (module docstring), else by newton.solve_step on the
    same step records (its work then counts both, and one fallback)."""
    warm = contacts.impulse.copy()
    step.use_indefinite(True)
    try:
        return _active_set_newton(step, contacts, v_minus, solver, tol, min(ITERATIONS, max_iterations), end_rows)
    except StepFailure as exc:
        tried = spent(exc) + StepStats(fallbacks=1)
    contacts.impulse[:] = warm
    step.use_indefinite(False)
    try:
        v, report, work = newton.solve_step(step, contacts, v_minus, solver, tol, max_iterations, misses_fail,
                                            end_rows)
    except StepFailure as exc:
        carrying(exc, tried + spent(exc))
        raise
    return v, report, tried + work


def _active_set_newton(step, contacts, v_minus, solver, tol, max_iterations, end_rows=None):
    """The iterations (module docstring): velocities, solve report and work (one dense solve on
    the contacts per iteration, counted as a sweep)."""
    its = backtracks = 0
    try:
        n, h, theta = step.n_dofs, step.h, step.theta
        diagonals = step.diagonals()
        soft_dofs = step.contact_dofs(contacts)
        v, v_free = step.initial_velocity(v_minus), np.zeros(n)
        contacts.impulse[:, 1] = 0.0
        r = contacts.impulse[:, 0]  # a view: the problem's impulses
        kept = None
        short = 0  # consecutive damped steps
        merit = None  # of the current iterate, from the last line search
        for it in range(1, max_iterations + 1):
            its += 1
            with TIMES("free velocity"):
                step.free_velocity(v, v_free, exact=True)
            kept = newton.contact_problem(step, contacts, soft_dofs, v_free, v_minus, kept)
            problem = kept[0]
            newton.relinearise_at(it, end_rows, contacts, problem, v)
            if it == 1:  # |W_ii| of the first iterate: the merit's scale for the whole step
                scale = np.maximum(np.abs(problem.W[:, 0, 0]), 1e-300)
            r_old = r.copy()
            with TIMES("contact solve"):
                active = np.flatnonzero(r > 0.0 if it == 1 and np.any(r > 0.0) else r - problem.normal_velocity(v) / scale > 0.0)
                r_hat = np.zeros_like(r)
                if active.size:
                    try:
                        r_hat[active] = np.linalg.solve(problem.normal_delassus(active), -problem.normal_velocity(v_free)[active])
                    except np.linalg.LinAlgError:
                        raise StepFailure(f"singular active Delassus block ({active.size} contacts, iteration {it})") from None
                r[:] = r_hat
                v_hat = v_free + step.compliance_times(problem.generalised_impulse(n))
            if not np.all(np.isfinite(v_hat)):
                raise StepFailure(f"non-finite velocities at active-set iteration {it}")
            with TIMES("line search"):
                a, merit = _line_search(step, problem, diagonals, v_free, scale, v, r_old, v_hat, r_hat, merit)
            backtracks += a < 1.0
            short = short + 1 if a < SHORT_STEP else 0
            if short == SHORT_STEPS:
                raise StepFailure(f"the active-set Newton stalled: {short} steps shorter than {SHORT_STEP} (iteration {it})")
            v_new = v + a * (v_hat - v)
            r[:] = r_old + a * (r_hat - r_old)
            err = h * theta * float(np.max(np.abs(v_new - v)))
            v = v_new
            if err <= tol and np.all(r >= 0.0):
                contact = solver.measure.error(problem, solver.tolerance, v)
                if np.all(problem.normal_velocity(v)[r == 0.0] >= -tol / (h * theta)) and contact <= solver.tolerance:
                    break
        else:
            raise StepFailure(f"the active-set Newton did not converge in {max_iterations} iterations")
        expected = step.expected_negative()
        if expected and not _negative_eigenvalues(problem, np.flatnonzero(r > 0.0)) == expected:
            raise StepFailure("the exact Newton matrix is not definite on what the active contacts leave free")
    except StepFailure as exc:
        carrying(exc, StepStats(its, its, backtracks))
        raise
    return v, SolveReport(v, it, contact), StepStats(its, its, backtracks)


def _line_search(step, problem, diagonals, v_free, scale, v, r, v_hat, r_hat, m0) -> tuple[float, float]:
    """The step a (module docstring): the first of 1, 1/2, ..., 1/1024 that keeps the areas and
    decreases the merit m0 of (v, r) (None: computed here) by 1e-4 a of its value; the last one
    tried if none does. Returns a and the merit there (None if it was not computed or did not
    decrease)."""
    if m0 is None:
        m0 = _merit(step, problem, diagonals, v_free, scale, v, r)
    a, m = 1.0, np.inf
    while a > 1e-3:
        trial = v + a * (v_hat - v)
        if newton.area_violation(step, trial) is None:
            try:
                m = _merit(step, problem, diagonals, v_free, scale, trial, r + a * (r_hat - r))
            except StepFailure:  # an inverted element at the trial point
                m = np.inf
            if m <= (1.0 - 1e-4 * a) * m0:
                break
        a *= 0.5
    return a, (m if m <= (1.0 - 1e-4 * a) * m0 else None)


def _merit(step, problem, diagonals, v_free, scale, v, r) -> float:
    """The merit of (v, r) (module docstring); r (nc,) normal impulses. Leaves problem.impulse
    holding r."""
    n = step.n_dofs
    problem.impulse[:, 0] = r
    f = -problem.generalised_impulse(n)  # −H r, then + F
    for dofs, inverse_mass in diagonals:
        moving = inverse_mass > 0.0
        f[dofs] += np.where(moving, (v[dofs] - v_free[dofs]) / np.where(moving, inverse_mass, 1.0), 0.0)
        f[dofs] = np.where(moving, f[dofs], 0.0)  # a held wall takes any impulse
    total = 0.0
    for g, st in step.iterated:
        fb = f[g.dofs].reshape(len(g), -1) + g.momentum_residual(st, v)
        vb = v[g.dofs].reshape(len(g), -1)
        c = g.held_directions()
        if c is not None:
            cc = np.einsum("ij,ij->i", c, c)
            fb = fb - (np.einsum("ij,ij->i", c, fb) / cc)[:, None] * c
            total += float(np.sum(np.einsum("ij,ij->i", c, vb) ** 2 / cc))
        f[g.dofs] = fb.ravel()
    complementarity = np.minimum(r, problem.normal_velocity(v) / scale)
    return total + float(f @ f) + float(complementarity @ complementarity)


def _negative_eigenvalues(problem, active: np.ndarray) -> int:
    """Negative eigenvalues of the active normal Delassus block; -1 if it has a zero one."""
    if not active.size:
        return 0
    e = np.linalg.eigvalsh(problem.normal_delassus(active))
    if np.abs(e).min() <= 1e-12 * np.abs(e).max():
        return -1
    return int(np.count_nonzero(e < 0.0))
