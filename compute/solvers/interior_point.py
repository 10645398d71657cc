r"""An interior-point method on the whole contact problem: the packing's contacts solved together,
in a number of iterations that barely grows with the packing or its stiffness.

Why: Gauss–Seidel (point or block) carries a load through a contact network one neighbour per
sweep, so a large, stiff packing needs thousands of sweeps (:mod:`compute.solvers`). A Newton-type
method on all contacts at once is not limited by the network's size.

Formulation. In 2D the Coulomb cone is polyhedral, so the Signorini–Coulomb problem
u = W r + q is exactly a linear complementarity problem (Stewart & Trinkle 1996): per frictional
contact the unknowns z = (r_n, β⁺, β⁻, λ) ≥ 0, r_t = β⁺ − β⁻, and

    w_n = ũ_n ≥ 0,   w⁺ = λ + u_t ≥ 0,   w⁻ = λ − u_t ≥ 0,   w_λ = μ r_n − β⁺ − β⁻ ≥ 0,   z ∘ w = 0

(λ is the slip speed: λ > 0 puts r_t on the cone's edge against u_t); a frictionless contact has
r_n alone. Impulses are scaled by ρ_c = 1 / W_nn,c (r = ρ z) so that every unknown has the
units of a velocity whatever the contact's compliance. w = M z + b with M constant: assembled
once per solve from the Delassus operator (:mod:`compute.contact.delassus`). (Writing friction
through De Saxcé's μ |u_t| term instead gives a complementarity problem with two unknowns per
contact but a Jacobian that switches with sgn u_t; the interior point then stalled on far more
of the random problems of the tests.) Where it does not converge: frictional rigid packings
with many redundant stick contacts (benchmarks/results/contact_problems.md).

Method: Mehrotra's predictor–corrector on z ∘ w = σ μ e (infeasible start, one step length for
z and w so that the residual M z + b − w shrinks by (1 − α) per iteration). Each iteration
solves the Newton system (M + diag(w / z)) Δz = g twice. Its β⁺, β⁻, λ rows are local to their
contact, so they are eliminated per contact: what is factorised (sparse LU, COLAMD column
ordering) is (W̃ + L) Δ(r_n, r_t) = g̃, two unknowns per contact (one without friction), W̃ = W ρ
and L a 2x2 block per contact (``_reduce``, ``_expand``): the pattern of W itself, 4/9 of the
entries and a quarter of the unknowns of the full system. The start
is scaled to the problem, z₀ = w₀ = the rms of q: the method needs a well-centred start more than
a close one, so a warm start is not used. Once the set of positive unknowns stops changing, a
crossover solves the law on it exactly (M_PP z_P = −b_P, the others zero; one factorisation and a
few refinement steps for redundant contacts), followed by a few primal-dual active-set steps
where that set was not quite right; kept if its error is smaller.

Stopping: the natural-map error of :mod:`compute.contact.residual` at most ``tolerance``,
evaluated on the impulses at every iteration, or ``max_iterations``; the best impulses found
are returned with their error (a miss shows as an error above the tolerance).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from compute.contact.delassus import Delassus
from compute.solvers.report import SolveReport
from compute.solvers.nlgs import apply_impulses
from compute.contact.residual import Measure, local_contact_error

STEP_TO_BOUNDARY = 0.99  # fraction of the step to the boundary of z, w > 0
SHORT_STEP = 0.1  # a corrector step shorter than this is replaced by a centring step
REGULARISATION = 1e-13  # relative, added to the diagonal (M is singular with redundant contacts)
REFINEMENTS = 3  # iterative refinement steps of a crossover solve
ACTIVE_SET_STEPS = 5  # primal-dual active-set steps of a crossover


@dataclass(frozen=True)
class InteriorPoint:
    """Mehrotra predictor–corrector on the whole contact problem (module docstring): stops when
    the natural-map error is at most ``tolerance`` or after ``max_iterations``."""

    tolerance: float
    max_iterations: int = 100
    measure: Measure = Measure()

    def solve(self, problem) -> SolveReport:
        """Solve ``problem`` (a ContactProblem), in place; its warm start is not used."""
        r, iterations, _ = solve_lcp(Delassus.of_problem(problem), local_free_velocity(problem), problem.mu,
                                     self.measure.codes(problem, self.tolerance), self.max_iterations)
        problem.impulse[:] = r
        v = problem.free_velocity()
        apply_impulses(problem.dof, problem.hn, problem.ht, problem.impulse, v, *problem.compliance.arrays())
        v = problem.velocities(v)
        return SolveReport(v, iterations, self.measure.error(problem, self.tolerance, v))


def local_free_velocity(problem) -> np.ndarray:
    """q (nc, 2) = (ũ_n, u_t) at zero impulses: Hᵀ v_free plus the gap term."""
    vp = problem.free_velocity()
    rows = np.where(problem.dof >= 0, vp[np.maximum(problem.dof, 0)], 0.0)
    return np.stack([np.sum(problem.hn * rows, axis=1) + problem.gap_term, np.sum(problem.ht * rows, axis=1)], 1)


def solve_lcp(W: Delassus, q: np.ndarray, mu: np.ndarray, codes: tuple, max_iterations: int):
    """Impulses r (nc, 2), iterations, error of u = W r + q (module docstring); ``codes`` the
    measure (kind, tol, bound) of :meth:`compute.contact.residual.Measure.codes`."""
    tol = codes[1]
    nc = len(W)
    if nc == 0:
        return np.zeros((0, 2)), 0, 0.0
    wnn = W.data[W.indptr[:-1] + diagonal_position(W.indptr, W.indices), 0, 0]
    rho = np.where(wnn > 0.0, 1.0 / np.where(wnn > 0.0, wnn, 1.0), 1.0)
    var0 = _variables(mu)
    vals, rows, cols = _lcp_entries(W.indptr, W.indices, W.data, var0, mu, rho)
    M = sp.csc_matrix((vals, (rows, cols)), shape=(var0[-1], var0[-1]))
    M.sum_duplicates()
    b = _lcp_offset(q, var0)
    m = b.size
    reg = REGULARISATION * max(float(np.abs(M.diagonal()).max()), 1.0)
    red0, colptr, rowind, pos = reduced_pattern(W.indptr, W.indices, var0)
    base = _reduced_base(W.indptr, W.indices, W.data, red0, rho, rowind.size)
    scale = max(float(np.sqrt(np.mean(q**2))), np.finfo(float).tiny)
    best, best_error = np.zeros((nc, 2)), np.inf
    tried = previous = None  # the active set whose crossover last failed; the last iterate's

    def stop(z, w, last):
        """The error of the iterate's impulses, kept if the best; a crossover once the set of
        positive unknowns repeats (module docstring)."""
        nonlocal best, best_error, tried, previous
        r = _impulses(z, var0, rho)
        error = solution_error(codes, wnn, W.times(r) + q, r, mu, q)
        if error < best_error:
            best, best_error = r, error
        if best_error <= tol or last:
            return True
        active = z > w
        if previous is not None and np.array_equal(active, previous) and not np.array_equal(active, tried):
            rx, ex = _crossover(M, b, active, reg, W, q, wnn, mu, var0, rho, codes)
            if ex < best_error:
                best, best_error = rx, ex
                if best_error <= tol:
                    return True
            tried = active
        previous = active
        return False

    def newton_system(d):
        """The solve of (M + diag(d)) Δz = g through the reduced system (module docstring)."""
        lu = spla.splu(sp.csc_matrix((_reduced_values(base, red0, pos, d, var0, mu), rowind, colptr),
                                     shape=(red0[-1], red0[-1])), permc_spec="COLAMD")
        return lambda g: _expand(lu.solve(_reduce(g, var0, red0, d, mu)), g, var0, red0, d, mu)

    _, _, it = predictor_corrector(lambda z: M @ z + b, newton_system, stop, np.full(m, scale), np.full(m, scale),
                                   max_iterations, reg)
    return best, it, best_error


def predictor_corrector(residual, newton_system, stop, z: np.ndarray, w: np.ndarray, max_iterations: int,
                        reg: float = 0.0):
    """Mehrotra's predictor–corrector on the LCP w = M z + b, 0 ≤ z ⊥ w ≥ 0, from z, w > 0 (m,)
    (infeasible: one step length for z and w, so that M z + b - w shrinks by 1 - α per
    iteration). ``residual(z)`` is M z + b; ``newton_system(d)`` factorises M + diag(d) (d (m,)
    = w / z + ``reg``) and returns its solve, g -> Δz; ``stop(z, w, last)`` is the caller's test
    at every iterate, ``last`` true once ``max_iterations`` are spent: True stops. Returns
    (z, w, iterations)."""
    m = z.size
    for it in range(max_iterations + 1):
        if stop(z, w, it == max_iterations) or it == max_iterations:
            break
        F = residual(z)
        d = w / z + reg
        newton = newton_system(d)
        gap = float(z @ w) / m
        dz = newton(-F)  # predictor (affine scaling): complementarity target 0
        dw = -w - d * dz
        ap, ad = _to_boundary(z, dz, 1.0), _to_boundary(w, dw, 1.0)
        sigma = min(1.0, (float((z + ap * dz) @ (w + ad * dw)) / m / gap) ** 3)
        rc = -z * w - dz * dw + sigma * gap  # corrector: centred, with the second-order term
        dz = newton(-F + w + rc / z)
        dw = (rc - w * dz) / z
        a = min(_to_boundary(z, dz, STEP_TO_BOUNDARY), _to_boundary(w, dw, STEP_TO_BOUNDARY))
        if a < SHORT_STEP:  # jammed against the boundary: a centring step instead
            rc = -z * w + gap
            dz = newton(-F + w + rc / z)
            dw = (rc - w * dz) / z
            a = min(_to_boundary(z, dz, STEP_TO_BOUNDARY), _to_boundary(w, dw, STEP_TO_BOUNDARY))
        z = z + a * dz
        w = w + a * dw
    return z, w, it


def _crossover(M, b, active, reg, W, q, wnn, mu, var0, rho, codes):
    """(r, error) of the best of a few primal-dual active-set steps from the set ``active`` (m,):
    solve M_PP z_P = -b_P with the others zero, then move to P' = {i in P: z_i > 0} ∪ {i not in P:
    w_i < 0}; P' = P is an exact solution. (None, inf) if no step could be taken."""
    best, best_error = None, np.inf
    P = np.flatnonzero(active)
    for _ in range(ACTIVE_SET_STEPS):
        z = np.zeros(b.size)
        if P.size:
            A = M[P][:, P].tocsc()
            A.setdiag(A.diagonal() + reg)
            try:
                lu = spla.splu(A, permc_spec="COLAMD")
            except RuntimeError:  # exactly singular
                break
            for _ in range(REFINEMENTS):  # iterative refinement: the regularisation's bias removed
                z[P] -= lu.solve((M @ z + b)[P])
        w = M @ z + b
        r = _impulses(np.maximum(z, 0.0), var0, rho)
        error = solution_error(codes, wnn, W.times(r) + q, r, mu, q)
        if error < best_error:
            best, best_error = r, error
        on = np.zeros(b.size, np.bool_)
        on[P] = True
        new = np.flatnonzero(np.where(on, z > 0.0, w < 0.0))
        if np.array_equal(new, P):
            break
        P = new
    return best, best_error


def _to_boundary(x: np.ndarray, dx: np.ndarray, eta: float) -> float:
    """The largest α ≤ 1 with x + α dx ≥ (1 - eta) x."""
    neg = dx < 0.0
    if not neg.any():
        return 1.0
    return min(1.0, eta * float(np.min(-x[neg] / dx[neg])))


@numba.njit(cache=True)
def diagonal_position(indptr, indices):
    """Position of block (c, c) within row c of a block-CSR (nc,)."""
    nc = indptr.size - 1
    out = np.zeros(nc, np.int64)
    for c in range(nc):
        for p in range(indptr[c], indptr[c + 1]):
            if indices[p] == c:
                out[c] = p - indptr[c]
    return out


@numba.njit(cache=True)
def _variables(mu):
    """var0 (nc + 1,): contact c owns the unknowns var0[c]:var0[c + 1], (r_n, β⁺, β⁻, λ) if
    μ > 0, else (r_n,)."""
    nc = mu.size
    var0 = np.zeros(nc + 1, np.int64)
    for c in range(nc):
        var0[c + 1] = var0[c] + (4 if mu[c] > 0.0 else 1)
    return var0


@numba.njit(cache=True)
def _lcp_entries(indptr, indices, data, var0, mu, rho):
    """M in triplets (values, rows, cols): the W part between the (r_n, β⁺, β⁻)
    unknowns of every pair of contacts with a block, the local λ rows and columns, and an explicit
    (zero) diagonal entry for every unknown (so that the crossover's regularisation of a
    diagonal changes values, not the sparsity structure)."""
    nc = indptr.size - 1
    cap = 0
    for d in range(nc):
        for p in range(indptr[d], indptr[d + 1]):
            c = indices[p]
            cap += min(3, var0[c + 1] - var0[c]) * min(3, var0[d + 1] - var0[d])
    cap += 5 * nc + var0[nc]
    rows = np.empty(cap, np.int64)
    cols = np.empty(cap, np.int64)
    vals = np.empty(cap)
    o = 0
    sign = np.array([1.0, 1.0, -1.0])  # n, β⁺, β⁻: the tangential part enters with + and -
    for d in range(nc):
        kd = min(3, var0[d + 1] - var0[d])
        for jj in range(kd):
            en = rho[d] if jj == 0 else 0.0  # column: the impulse of unknown jj, scaled
            et = 0.0 if jj == 0 else sign[jj] * rho[d]
            for p in range(indptr[d], indptr[d + 1]):
                c = indices[p]  # block W[d, c]; W[c, d] is its transpose
                wn = data[p, 0, 0] * en + data[p, 1, 0] * et
                wt = data[p, 0, 1] * en + data[p, 1, 1] * et
                for ii in range(min(3, var0[c + 1] - var0[c])):
                    rows[o] = var0[c] + ii
                    cols[o] = var0[d] + jj
                    vals[o] = wn if ii == 0 else sign[ii] * wt
                    o += 1
        if var0[d + 1] - var0[d] == 4:  # w± = λ ± u_t, w_λ = μ r_n - β⁺ - β⁻ (in units of ρ)
            for ii, j, v in ((1, 3, 1.0), (2, 3, 1.0), (3, 0, mu[d]), (3, 1, -1.0), (3, 2, -1.0)):
                rows[o] = var0[d] + ii
                cols[o] = var0[d] + j
                vals[o] = v
                o += 1
    for i in range(var0[nc]):
        rows[o] = i
        cols[o] = i
        vals[o] = 0.0
        o += 1
    return vals[:o], rows[:o], cols[:o]


@numba.njit(cache=True)
def _lcp_offset(q, var0):
    """b (m,): (q_n, q_t, -q_t, 0) per frictional contact, q_n per frictionless one."""
    nc = var0.size - 1
    b = np.zeros(var0[nc])
    for c in range(nc):
        b[var0[c]] = q[c, 0]
        if var0[c + 1] - var0[c] == 4:
            b[var0[c] + 1] = q[c, 1]
            b[var0[c] + 2] = -q[c, 1]
    return b


@numba.njit(cache=True)
def _impulses(z, var0, rho):
    """r (nc, 2): r_c = ρ_c (r_n, β⁺ - β⁻)."""
    nc = var0.size - 1
    r = np.zeros((nc, 2))
    for c in range(nc):
        r[c, 0] = rho[c] * z[var0[c]]
        if var0[c + 1] - var0[c] == 4:
            r[c, 1] = rho[c] * (z[var0[c] + 1] - z[var0[c] + 2])
    return r


def solution_error(codes, wnn, u, r, mu, q):
    """The error (compute.contact.residual) of impulses r (nc, 2) from local velocities u (nc, 2)
    = W r + q."""
    size = np.abs(q).sum(axis=1) + np.abs(u).sum(axis=1)
    return local_contact_error(*codes, wnn, u, u - q, r, mu, size)


@numba.njit(cache=True)
def reduced_pattern(indptr, indices, var0):
    """The reduced Newton system's unknowns and CSC pattern: red0 (nc + 1,) (contact c owns
    red0[c]:red0[c + 1], (r_n, r_t) or (r_n,)), colptr, rowind (rows sorted), and pos (nc, 3) the
    positions of its diagonal block's entries (n, n), (t, n), (t, t) (-1: none)."""
    nc = indptr.size - 1
    red0 = np.zeros(nc + 1, np.int64)
    for c in range(nc):
        red0[c + 1] = red0[c] + (2 if var0[c + 1] - var0[c] == 4 else 1)
    n = red0[nc]
    colptr = np.zeros(n + 1, np.int64)
    for d in range(nc):
        count = 0
        for p in range(indptr[d], indptr[d + 1]):
            c = indices[p]
            count += red0[c + 1] - red0[c]
        for j in range(red0[d], red0[d + 1]):
            colptr[j + 1] = count
    for j in range(n):
        colptr[j + 1] += colptr[j]
    rowind = np.empty(colptr[n], np.int64)
    pos = np.full((nc, 3), -1, np.int64)
    for d in range(nc):
        for jj in range(red0[d + 1] - red0[d]):
            o = colptr[red0[d] + jj]
            for p in range(indptr[d], indptr[d + 1]):
                c = indices[p]
                for ii in range(red0[c + 1] - red0[c]):
                    rowind[o] = red0[c] + ii
                    if c == d:
                        if ii == 0 and jj == 0:
                            pos[d, 0] = o
                        elif ii == 1 and jj == 0:
                            pos[d, 1] = o
                        elif ii == 1 and jj == 1:
                            pos[d, 2] = o
                    o += 1
    return red0, colptr, rowind, pos


@numba.njit(cache=True)
def _reduced_base(indptr, indices, data, red0, rho, nnz):
    """The W̃ = W ρ part of the reduced matrix in the pattern of ``reduced_pattern``: row i of
    contact c, column j of contact d: (W[c, d] ρ_d e_j)_i, e_n = (1, 0), e_t = (0, 1)."""
    nc = indptr.size - 1
    vals = np.empty(nnz)
    o = 0
    for d in range(nc):
        for jj in range(red0[d + 1] - red0[d]):
            for p in range(indptr[d], indptr[d + 1]):
                c = indices[p]  # block W[d, c]; W[c, d] is its transpose
                for ii in range(red0[c + 1] - red0[c]):
                    vals[o] = data[p, jj, ii] * rho[d]
                    o += 1
    return vals


@numba.njit(cache=True)
def _reduced_values(base, red0, pos, d, var0, mu):
    """W̃ + L: per contact L = [[D_n, 0], [-μ (D⁻ - D⁺) / den, k' / den]] (frictionless: [[D_n]]),
    with D = w / z of its unknowns (n, +, -, λ), k' = D⁺ + D⁻ + D_λ D⁺ D⁻, den = 4 + (D⁺ + D⁻) D_λ:
    what is left of the rows n, +, -, λ once β⁺, β⁻, λ are eliminated (module docstring)."""
    vals = base.copy()
    for c in range(red0.size - 1):
        v = var0[c]
        vals[pos[c, 0]] += d[v]
        if var0[c + 1] - v == 4:
            dp, dm, dl = d[v + 1], d[v + 2], d[v + 3]
            den = 4.0 + (dp + dm) * dl
            vals[pos[c, 1]] -= mu[c] * (dm - dp) / den
            vals[pos[c, 2]] += (dp + dm + dl * dp * dm) / den
    return vals


@numba.njit(cache=True)
def _reduce(g, var0, red0, d, mu):
    """Right-hand side of the reduced system (n_red,) from the full one g (m,): g_n, and for a
    frictional contact [g⁺ (2 + D_λ D⁻) - g⁻ (2 + D_λ D⁺) - (D⁻ - D⁺) g_λ] / den."""
    out = np.empty(red0[-1])
    for c in range(red0.size - 1):
        v = var0[c]
        out[red0[c]] = g[v]
        if var0[c + 1] - v == 4:
            dp, dm, dl = d[v + 1], d[v + 2], d[v + 3]
            den = 4.0 + (dp + dm) * dl
            out[red0[c] + 1] = (g[v + 1] * (2.0 + dl * dm) - g[v + 2] * (2.0 + dl * dp) - (dm - dp) * g[v + 3]) / den
    return out


@numba.njit(cache=True)
def _expand(x, g, var0, red0, d, mu):
    """The full Newton step Δz (m,) from the reduced one x = (Δr_n, Δr_t) per contact: the
    tangential velocity U_t from the reduced t row, then Δλ from the rows +, -, λ, then
    Δβ± = (Δσ ± Δr_t) / 2 with Δσ = Δβ⁺ + Δβ⁻ from the λ row (no division by a small D)."""
    dz = np.empty(var0[-1])
    for c in range(red0.size - 1):
        v = var0[c]
        da = x[red0[c]]
        dz[v] = da
        if var0[c + 1] - v == 4:
            dt = x[red0[c] + 1]
            dp, dm, dl = d[v + 1], d[v + 2], d[v + 3]
            den = 4.0 + (dp + dm) * dl
            kk = dp + dm + dl * dp * dm
            gt = (g[v + 1] * (2.0 + dl * dm) - g[v + 2] * (2.0 + dl * dp) - (dm - dp) * g[v + 3]) / den
            ut = gt - kk / den * dt + mu[c] * (dm - dp) / den * da
            dlam = (dp * dm * g[v + 3] + dm * g[v + 1] + dp * g[v + 2] - dp * dm * mu[c] * da - (dm - dp) * ut) / kk
            dsig = mu[c] * da + dl * dlam - g[v + 3]
            dz[v + 1] = 0.5 * (dsig + dt)
            dz[v + 2] = 0.5 * (dsig - dt)
            dz[v + 3] = dlam
    return dz
