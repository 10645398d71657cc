r"""An interior point for jammed frictional packings: De Saxcé's shift as a fixed point, each
step a monotone complementarity problem over the Coulomb cone.

Why: the interior point of :mod:`compute.solvers.interior_point` works on the Stewart–Trinkle
LCP, whose friction rows make it non-monotone; on a jammed frictional rigid packing (many
redundant, sticking contacts) its error stalls near 1e-4 (benchmarks/results/contact_problems.md).

Formulation. The Signorini–Coulomb law of contact c is, in De Saxcé's form,
K* ∋ ū_c ⊥ r_c ∈ K_c with ū = (ũ_n + μ |u_t|, u_t) and K = {|r_t| ≤ μ r_n}
(:mod:`compute.contact.residual`). With the shift s_c in place of μ |u_t| held fixed it is the
optimality system of the convex quadratic programme min ½ rᵀ W r + (q + s e_n)ᵀ r over the
cones, u = W r + q. In 2D the cone has two edges, r_c = √ρ_c (a_c e⁺_c + b_c e⁻_c),
e± = (1, ±μ_c), a, b ≥ 0 (a frictionless contact: r_c = √ρ_c a_c (1, 0)), and the programme is
the LCP

    w = M z + b(s) ≥ 0,  z = (a, b) ≥ 0,  z ∘ w = 0,   M = Aᵀ W A,  b(s) = Aᵀ (q + s e_n),

A block-diagonal with columns √ρ_c e±_c: M is symmetric positive semi-definite, so the LCP is
monotone, which is what an interior point solves reliably; w_c = √ρ_c (ū_n ± μ u_t) are the
velocities along the dual cone's edges. ρ_c = 1 / W_nn,c scales each contact as in the
interior point, here on both sides (Jacobi scaling of W, M's diagonal about 1 + μ²) so that M
stays symmetric. Two unknowns per frictional contact: the Newton matrix M + diag(w / z) has
the pattern of W (2x2 blocks), assembled per contact (numba) and factorised by sparse LU
(symmetric mode: M + diag(w / z) is positive definite), half the unknowns of the
Stewart–Trinkle system before its reduction and the same count after it. The predictor–corrector is
:func:`compute.solvers.interior_point.predictor_corrector`, from a cold, centred start
z = w = rms(b) at every outer step.

Outer iteration: a solution of the LCP with s = μ |u_t| is a Coulomb solution, so
s ← (1 − θ) s + θ μ |u_t(s)| (``damping`` θ, 1 by default: undamped, the error fell fastest
per step on the rigid packings tried; benchmarks/results/design_figures.md). The first s is
μ |u_t| of the warm-start impulses'
velocities, for zero impulses of the free velocity: with s = 0 a cone LCP can have no solution
(a self-stress inside the cones whose cost (q + s e_n)ᵀ r is negative, seen on the rank-deficient
test problems with overlapping gaps), and its interior point then runs the impulses to infinity,
where the relative error ‖f‖ / ‖r‖ is fooled. For the same reason each LCP carries a proximal
term ε/2 |r − r̄|² weighted by W_nn (ε = ``PROXIMAL``, r̄ the last outer step's impulses):
strictly monotone, bounded, and exact at a fixed point (r = r̄). Each LCP is solved until its own
(shifted, proximal) natural-map error is ``INNER`` times the tolerance; the true error of the
measure is evaluated at every interior-point iterate, and the solve stops as soon as it is at
most the tolerance.

Polish: the fixed point converges linearly and stalls on jammed packings (contacts flickering
between stick and slip; benchmarks/results/contact_problems.md). Once an
outer step does not halve the error (``STALL``), at most ``polish`` Levenberg–Marquardt steps on
the Alart–Curnier function take over from the best impulses (``levenberg_marquardt``). The best
impulses found are returned with their error.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from compute.contact.delassus import Delassus
from compute.solvers.report import SolveReport
from compute.solvers.interior_point import (REGULARISATION, _variables, diagonal_position, local_free_velocity,
                                            predictor_corrector, reduced_pattern, solution_error)
from compute.solvers.nlgs import apply_impulses
from compute.contact.residual import Measure, local_contact_error

INNER = 0.1  # an outer step's LCP is solved to this fraction of the tolerance (its own error)
PROXIMAL = 1e-6  # ε of the proximal term ε/2 |r - r̄|²_P, relative to W_nn (module docstring)
STALL = 0.5  # the fixed point has stalled when an outer step does not divide the error by 2
LM_DAMPING = 1e-3  # Levenberg–Marquardt's λ over |F|
ARMIJO = 1e-4  # sufficient decrease of |F|² of a Levenberg–Marquardt step
ARMIJO_HALVINGS = 30
# Both Newton matrices are symmetric positive definite: a symmetric ordering, no pivoting (faster
# factorisations than COLAMD's: benchmarks/results/contact_problems.md).
SYMMETRIC = {"permc_spec": "MMD_AT_PLUS_A", "diag_pivot_thresh": 0.0, "options": {"SymmetricMode": True}}


@dataclass(frozen=True)
class ConePoint:
    """De Saxcé shift fixed point over monotone cone LCPs solved by an interior point (module
    docstring): stops when the error of ``measure`` is at most ``tolerance``, after
    ``max_iterations`` interior-point iterations in all, or after ``outer`` shift updates;
    ``damping`` θ in (0, 1] of the shift update."""

    tolerance: float
    max_iterations: int = 200
    measure: Measure = Measure()
    outer: int = 10
    damping: float = 1.0
    polish: int = 20  # Levenberg–Marquardt iterations once the fixed point stalls (0: none)

    def solve(self, problem) -> SolveReport:
        """Solve ``problem`` (a ContactProblem), in place; its warm start gives the first shift."""
        W = Delassus.of_problem(problem)
        r, iterations, _ = solve_cone(W, local_free_velocity(problem), problem.mu,
                                      self.measure.codes(problem, self.tolerance), problem.impulse,
                                      self.max_iterations, self.outer, self.damping, self.polish)
        problem.impulse[:] = r
        v = problem.free_velocity()
        apply_impulses(problem.dof, problem.hn, problem.ht, problem.impulse, v, *problem.compliance.arrays())
        v = problem.velocities(v)
        return SolveReport(v, iterations, self.measure.error(problem, self.tolerance, v))


class ConeLCP:
    """The cone LCP of a problem u = W r + q (module docstring), for any shift s (nc,):
    ``var0`` (nc + 1,) (contact c owns z[var0[c]:var0[c + 1]], (a, b) or (a,)), ``M`` (csc)."""

    def __init__(self, W: Delassus, q: np.ndarray, mu: np.ndarray, prox: float = 0.0):
        self.W, self.q, self.mu, self.prox = W, q, mu, prox
        self.wnn = W.data[W.indptr[:-1] + diagonal_position(W.indptr, W.indices), 0, 0]
        rho = np.where(self.wnn > 0.0, 1.0 / np.where(self.wnn > 0.0, self.wnn, 1.0), 1.0)
        self.sr = np.sqrt(rho)
        self.var0, self.colptr, self.rowind, pos = reduced_pattern(W.indptr, W.indices, _variables(mu))
        m = self.var0[-1]
        self.values = _cone_entries(W.indptr, W.indices, W.data, self.var0, mu, self.sr, self.rowind.size, prox)
        self.P = 1.0 / (self.sr * self.sr)  # the proximal metric per contact, W_nn (1 without compliance)
        self.M = sp.csc_matrix((self.values, self.rowind, self.colptr), shape=(m, m))
        self.diagonal = np.empty(m, np.int64)  # position of each unknown's diagonal entry in ``values``
        self.diagonal[self.var0[:-1]] = pos[:, 0]
        friction = np.diff(self.var0) == 2
        self.diagonal[self.var0[:-1][friction] + 1] = pos[friction, 2]
        self.reg = REGULARISATION * max(float(np.abs(self.values[self.diagonal]).max()), 1.0)

    def offset(self, s: np.ndarray, centre: np.ndarray) -> np.ndarray:
        """b (m,) = Aᵀ (q + s e_n - ε P r̄), r̄ (nc, 2) the proximal centre."""
        return _cone_offset(self.q - self.prox * self.P[:, None] * centre, s, self.var0, self.mu, self.sr)

    def impulses(self, z: np.ndarray) -> np.ndarray:
        """r (nc, 2) = A z."""
        return _cone_impulses(z, self.var0, self.mu, self.sr)

    def newton_system(self, d: np.ndarray):
        """The solve g -> Δz of (M + diag(d)) Δz = g (sparse LU, symmetric mode)."""
        values = self.values.copy()
        values[self.diagonal] += d
        m = d.size
        return spla.splu(sp.csc_matrix((values, self.rowind, self.colptr), shape=(m, m)), **SYMMETRIC).solve

    def solve(self, s: np.ndarray, centre: np.ndarray, stop, max_iterations: int):
        """(z, w, iterations) of the interior point on the LCP of shift s and proximal centre
        ``centre`` from a centred cold start; ``stop(z, w, last)`` as in
        :func:`compute.solvers.interior_point.predictor_corrector`."""
        b = self.offset(s, centre)
        scale = max(float(np.sqrt(np.mean(b**2))), np.finfo(float).tiny)
        return predictor_corrector(lambda z: self.M @ z + b, self.newton_system, stop, np.full(b.size, scale),
                                   np.full(b.size, scale), max_iterations, self.reg)

    def shifted_error(self, codes, u: np.ndarray, r: np.ndarray, s: np.ndarray, centre: np.ndarray) -> float:
        """The error of ``codes``' kind (no penetration test) of impulses r (nc, 2) with velocities
        u = W r + q (nc, 2) as a solution of the LCP of shift s and proximal centre ``centre``: the
        law with s for μ |u_t| and u + ε P (r - r̄) for u."""
        u = u + self.prox * self.P[:, None] * (r - centre)
        shifted = u.copy()
        shifted[:, 0] += s - self.mu * np.abs(u[:, 1])  # the natural map adds μ |u_t| back
        size = np.abs(self.q).sum(axis=1) + np.abs(u).sum(axis=1) + s
        return local_contact_error(codes[0], codes[1], 0.0, self.wnn, shifted, u - self.q, r, self.mu, size)


def solve_cone(W: Delassus, q: np.ndarray, mu: np.ndarray, codes: tuple, warm: np.ndarray, max_iterations: int,
               outer: int, damping: float, polish: int = 0):
    """Impulses r (nc, 2), iterations (interior point and Levenberg–Marquardt), error of
    u = W r + q (module docstring); ``codes`` the measure (kind, tol, bound) of
    :meth:`compute.contact.residual.Measure.codes`, ``warm`` (nc, 2) impulses whose velocities
    give the first shift (none if zero)."""
    tol = codes[1]
    nc = len(W)
    if nc == 0:
        return np.zeros((0, 2)), 0, 0.0
    lcp = ConeLCP(W, q, mu, PROXIMAL)
    s = mu * np.abs((W.times(warm) + q)[:, 1])  # the warm start's shift; for zero impulses, the free velocity's
    best = centre = r = np.zeros((nc, 2))
    u = q
    best_error = solution_error(codes, lcp.wnn, u, r, mu, q)  # zero where every contact opens at r = 0
    total = 0
    if best_error <= tol:
        return best, total, best_error

    def stop(z, w, last):
        nonlocal best, best_error, u, r
        r = lcp.impulses(z)
        u = W.times(r) + q
        error = solution_error(codes, lcp.wnn, u, r, mu, q)
        if error < best_error:
            best, best_error = r, error
        return best_error <= tol or last or lcp.shifted_error(codes, u, r, s, centre) <= INNER * tol

    previous = np.inf  # the error at the end of the last outer step
    for _ in range(outer):
        _, _, iterations = lcp.solve(s, centre, stop, max_iterations - total)
        total += iterations
        if best_error <= tol or total >= max_iterations or best_error > STALL * previous:
            break
        previous = best_error
        s = (1.0 - damping) * s + damping * mu * np.abs(u[:, 1])
        centre = r
    if best_error > tol and polish > 0:
        r, iterations, error = levenberg_marquardt(W, q, mu, lcp.wnn, codes, best, polish)
        total += iterations
        if error < best_error:
            best, best_error = r, error
    return best, total, best_error


def levenberg_marquardt(W: Delassus, q: np.ndarray, mu: np.ndarray, wnn: np.ndarray, codes: tuple, r: np.ndarray,
                        max_iterations: int):
    """(r, iterations, error) of at most ``max_iterations`` Levenberg–Marquardt steps from
    impulses r (nc, 2) on the Alart–Curnier function F(r) (``_alart_curnier``), which is zero
    exactly at a Coulomb solution and piecewise affine in r, J = D_r + D_u W per piece:
    (Jᵀ J + λ I) Δr = -Jᵀ F with λ = ``LM_DAMPING`` |F| (J is singular where redundant contacts
    stick), then halving the step until |F|² decreases (Armijo). Stops on the error of ``codes``;
    returns the best impulses met."""
    tol = codes[1]
    nc = len(W)
    rho = np.where(wnn > 0.0, 1.0 / np.where(wnn > 0.0, wnn, 1.0), 1.0)
    Wsp = sp.bsr_matrix((W.data, W.indices, W.indptr), shape=(2 * nc, 2 * nc)).tocsr()
    block = np.arange(nc + 1), np.arange(nc)

    def evaluate(r):
        u = W.times(r) + q
        return u, solution_error(codes, wnn, u, r, mu, q), *_alart_curnier(u, r, mu, rho)

    u, error, F, Dr, Du = evaluate(r)
    best, best_error = r, error
    for it in range(max_iterations):
        if best_error <= tol:
            break
        J = (sp.bsr_matrix((Dr, block[1], block[0]), shape=(2 * nc, 2 * nc))
             + sp.bsr_matrix((Du, block[1], block[0]), shape=(2 * nc, 2 * nc)) @ Wsp).tocsr()
        f = F.ravel()
        size = float(f @ f)
        g = J.T @ f
        A = (J.T @ J + LM_DAMPING * np.sqrt(size) * sp.identity(2 * nc)).tocsc()
        step = -spla.splu(A, **SYMMETRIC).solve(g).reshape(nc, 2)
        t = 1.0
        for _ in range(ARMIJO_HALVINGS):
            trial = evaluate(r + t * step)
            if float(np.sum(trial[2] ** 2)) <= size + ARMIJO * t * float(g @ step.ravel()):
                break
            t *= 0.5
        r = r + t * step
        u, error, F, Dr, Du = trial
        if error < best_error:
            best, best_error = r, error
    else:
        it = max_iterations
    return best, it, best_error


@numba.njit(cache=True)
def _cone_entries(indptr, indices, data, var0, mu, sr, nnz, prox):
    """M = Aᵀ (W + ε P) A in the CSC pattern of :func:`compute.solvers.interior_point.reduced_pattern`
    (unknowns ``var0``): row ii of contact c, column jj of contact d: √ρ_c √ρ_d (E_cᵀ W[c, d] E_d)
    with E = [[1, 1], [μ, -μ]] (frictional) or [[1], [0]], plus ε E_cᵀ E_c on the diagonal
    blocks (ε = ``prox``, P = diag(1 / ρ))."""
    nc = indptr.size - 1
    vals = np.empty(nnz)
    o = 0
    for d in range(nc):
        for jj in range(var0[d + 1] - var0[d]):
            td = 0.0 if var0[d + 1] - var0[d] == 1 else (mu[d] if jj == 0 else -mu[d])  # t of d's edge jj
            for p in range(indptr[d], indptr[d + 1]):
                c = indices[p]  # block W[d, c]; W[c, d] = data[p]ᵀ
                wnn, wnt, wtn, wtt = data[p, 0, 0], data[p, 1, 0], data[p, 0, 1], data[p, 1, 1]
                col_n = wnn + wnt * td  # W[c, d] (1, td): n and t rows
                col_t = wtn + wtt * td
                for ii in range(var0[c + 1] - var0[c]):
                    tc = 0.0 if var0[c + 1] - var0[c] == 1 else (mu[c] if ii == 0 else -mu[c])
                    vals[o] = sr[c] * sr[d] * (col_n + tc * col_t) + (prox * (1.0 + tc * td) if c == d else 0.0)
                    o += 1
    return vals


@numba.njit(cache=True)
def _cone_offset(q, s, var0, mu, sr):
    """b (m,) = Aᵀ (q + s e_n): √ρ_c (q_n + s ± μ q_t) per frictional contact, √ρ_c q_n without."""
    nc = var0.size - 1
    b = np.empty(var0[nc])
    for c in range(nc):
        n = q[c, 0] + s[c]
        if var0[c + 1] - var0[c] == 2:
            b[var0[c]] = sr[c] * (n + mu[c] * q[c, 1])
            b[var0[c] + 1] = sr[c] * (n - mu[c] * q[c, 1])
        else:
            b[var0[c]] = sr[c] * q[c, 0]
    return b


@numba.njit(cache=True)
def _cone_impulses(z, var0, mu, sr):
    """r (nc, 2) = A z: √ρ_c (a + b, μ (a - b)), or √ρ_c (a, 0)."""
    nc = var0.size - 1
    r = np.zeros((nc, 2))
    for c in range(nc):
        if var0[c + 1] - var0[c] == 2:
            a, b = z[var0[c]], z[var0[c] + 1]
            r[c, 0] = sr[c] * (a + b)
            r[c, 1] = sr[c] * mu[c] * (a - b)
        else:
            r[c, 0] = sr[c] * z[var0[c]]
    return r


@numba.njit(cache=True)
def _alart_curnier(u, r, mu, rho):
    """Alart–Curnier's F (nc, 2) of impulses r with velocities u (nc, 2) and its Jacobian
    blocks D_r, D_u (nc, 2, 2) (F' = D_r + D_u W): F_n = r_n - max(0, r_n - ρ ũ_n),
    F_t = r_t - P_[-μ r_n⁺, μ r_n⁺](r_t - ρ u_t)."""
    nc = u.shape[0]
    F = np.empty((nc, 2))
    Dr = np.zeros((nc, 2, 2))
    Du = np.zeros((nc, 2, 2))
    for c in range(nc):
        if r[c, 0] - rho[c] * u[c, 0] > 0.0:
            F[c, 0] = rho[c] * u[c, 0]
            Du[c, 0, 0] = rho[c]
        else:
            F[c, 0] = r[c, 0]
            Dr[c, 0, 0] = 1.0
        bound = mu[c] * max(r[c, 0], 0.0)
        y = r[c, 1] - rho[c] * u[c, 1]
        if abs(y) <= bound:  # stick (a positive bound)
            F[c, 1] = rho[c] * u[c, 1]
            Du[c, 1, 1] = rho[c]
        else:
            sign = 1.0 if y > 0.0 else -1.0
            F[c, 1] = r[c, 1] - sign * bound
            Dr[c, 1, 1] = 1.0
            if r[c, 0] > 0.0:
                Dr[c, 1, 0] = -sign * mu[c]
    return F, Dr, Du
