r"""Frictionless contact as a bound-constrained quadratic program, solved by MPRGP.

Without friction the contact problem of a step is the linear complementarity problem

    ũ_n = W_nn r_n + q_n ≥ 0,   r_n ≥ 0,   ũ_n · r_n = 0,

W_nn = H_nᵀ M̂⁻¹ H_n symmetric positive semidefinite (singular where contacts are redundant), so
r_n minimises ½ r_nᵀ W_nn r_n + q_nᵀ r_n over r_n ≥ 0: a convex quadratic program whose gradient
is ũ_n. Point Gauss–Seidel is coordinate descent on it and needs a number of sweeps that grows
with the packing's size and stiffness; conjugate gradients with projections carry a load across
the whole packing at each iteration (figures: benchmarks/results/frictionless_qp.md).

Method: MPRGP, modified proportioning with reduced gradient projections (Dostál & Schöberl
2005, Comput. Optim. Appl. 30: 23–43), on the problem scaled by s_c = 1 / sqrt(W_nn,c) (unit
diagonal, the bounds unchanged). With g = W r + q, the free set F = {r_c > 0}, the free
gradient φ (g on F, 0 elsewhere), the chopped gradient β (min(g, 0) off F, 0 on F) and the
reduced free gradient φ̃ = min(r / ᾱ, φ) on F:

- proportional iterate (|β|² ≤ Γ² φ̃ᵀφ): a conjugate-gradient step on the free set, or, when it
  would leave r ≥ 0, the feasible part of it followed by a projected gradient step of length
  ᾱ = 1.9 / λ (an expansion: the free set may grow by many contacts at once);
- otherwise a proportioning step along β (contacts released from r = 0).

Each iteration costs one product with W_nn (:func:`_times`), in the cheapest form for each part
(:func:`compute.contact.delassus.normal_groups`): the rigid and wall dofs' part H_nᵀ D H_n
through the 1x1 compliance blocks D (a scatter and a gather over the rows); a soft body with
fewer contacts k than contact dofs s as its own dense k × k W_G = H_G,nᵀ C_G H_G,n, built once
per solve; a body crowded with contacts (soft–soft rows both ways) through its s × s
compliance block C_G, one dense product per body. Both are symmetric and kept as packed upper
triangles, each value read once for two products (:func:`compute.contact.delassus.packed_times`):
reading them is most of a product's cost once a packing's blocks outgrow the caches. (The whole W assembled in block-CSR,
:class:`compute.contact.delassus.Delassus`, costs more to build for each new problem than the
iterations it would save: a problem lasts about two solves in a mixture's Newton loop.)

The step ᾱ: Dostál's theory takes ᾱ ∈ (0, 2 / ‖W‖]; what its decrease estimate uses of that is
dᵀW d ≤ (2 / ᾱ) dᵀd along the step d taken. So λ is the largest curvature dᵀW d / dᵀd of the
directions the iteration has met (conjugate-gradient, proportioning and expansion steps; a
lower bound of ‖W‖, 1 to start with: the unit diagonal), and an expansion whose own step d
has ᾱ dᵀW d > 2 dᵀd is redone with λ raised to that curvature. Each accepted expansion then
lowers the quadratic (f(y) − f(y½) = g½ᵀd + ½ dᵀW d ≤ −dᵀd / ᾱ + ½ dᵀW d ≤ 0, d being a
projected gradient step), and ᾱ is as long as the curvatures met allow, with no estimate of
‖W‖ beforehand (six power iterations per solve, before; what that saves is in
benchmarks/results/mprgp_step_length.md); W d is free, the difference of the two gradients. A
warm start that already meets the tolerance costs one product.

The method is warm-started from the problem's impulses (the last Newton iteration's). Stopping: the
error of :mod:`compute.contact.residual` in the scene's measure at most ``tolerance``, on the
iterate (the recurrence's g, recomputed exactly before the stop is accepted), or
``max_iterations``; the velocity measures are judged there on the normal part of W r alone,
which can only stop later than the full measure (reported at the end) would. Only for problems
without friction: a contact with μ > 0 is an error.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from compute.contact.delassus import normal_groups, packed_times
from compute.contact.residual import Measure, add_contact, error_of_sums, squared_normal_error
from compute.fixed_order import dot
from compute.solvers.interior_point import local_free_velocity
from compute.solvers.nlgs import apply_impulses
from compute.solvers.report import SolveReport

GAMMA = 1.0  # proportioning parameter Γ (Dostál's usual choice)
EXPANSION = 1.9  # ᾱ λ: the projected gradient step of an expansion, in (0, 2), λ the largest curvature met


@dataclass(frozen=True)
class MPRGP:
    """Frictionless contact by MPRGP (module docstring): stops when the error in ``measure`` is
    at most ``tolerance`` or after ``max_iterations``."""

    tolerance: float
    max_iterations: int
    measure: Measure = Measure()

    def solve(self, problem) -> SolveReport:
        """Solve ``problem`` (a ContactProblem without friction) from its warm-start impulses, in place."""
        if np.any(problem.mu > 0.0):
            raise ValueError("MPRGP solves frictionless contact problems only: a contact has μ > 0")
        iterations = 0
        c = problem.compliance
        if len(problem):
            q = local_free_velocity(problem)
            r = np.zeros((len(problem), 2))
            r[:, 0] = problem.impulse[:, 0]
            groups = normal_groups(problem.dof, problem.hn, c.block, c.start, c.offset, c.values)
            op = (problem.dof, problem.hn, *c.arrays(), *groups)
            iterations = mprgp(op, np.ascontiguousarray(problem.W[:, 0, 0]), q, r,
                               *self.measure.codes(problem, self.tolerance), self.max_iterations)
            problem.impulse[:] = r
        v = problem.free_velocity()
        apply_impulses(problem.dof, problem.hn, problem.ht, problem.impulse, v, *c.arrays())
        v = problem.velocities(v)
        return SolveReport(v, iterations, self.measure.error(problem, self.tolerance, v))


@numba.njit(cache=True)
def _times(op, s, x, work, out):
    """out = S W_nn S x (nc,) for x (nc,), S = diag(s), W_nn given by ``op`` = (dof, hn, diagonal,
    block, start, offset, values, dense, ptr, contacts, woff, wval, coff, cval) in the two forms
    of :func:`compute.contact.delassus.normal_groups`: through the compliance (the 1x1 blocks
    ``diagonal``, the packed triangles ``cval`` of the blocks without their W_G) as a scatter of
    the rows' entries onto the dofs, one product per block and a gather; through the packed W_G
    for the others, on their contacts gathered. ``work``: :func:`_work`'s arrays for ``op`` (hx
    zero on entry and on return)."""
    diagonal, start, ptr, contacts, woff, wval, coff, cval = op[2], op[4], op[8], op[9], op[10], op[11], op[12], op[13]
    xs, hx, vx, gx, gy, eptr, edof, eh, diag_dofs, blocks = work
    nc = xs.size
    for c in range(nc):
        xs[c] = s[c] * x[c]
    for c in range(nc):  # hx = H_n xs on the dofs applied through the compliance
        if xs[c] != 0.0:
            for e in range(eptr[c], eptr[c + 1]):
                hx[edof[e]] += eh[e] * xs[c]
    for d in diag_dofs:  # vx = C hx, zeroing hx behind it
        vx[d] = diagonal[d] * hx[d]
        hx[d] = 0.0
    for g in blocks:
        s0, s1 = start[g], start[g + 1]
        vx[s0:s1] = 0.0
        packed_times(cval[coff[g]:coff[g + 1]], s1 - s0, hx[s0:s1], vx[s0:s1])
        hx[s0:s1] = 0.0
    for c in range(nc):  # out = H_nᵀ vx
        u = 0.0
        for e in range(eptr[c], eptr[c + 1]):
            u += eh[e] * vx[edof[e]]
        out[c] = u
    for i in range(gx.size):
        gx[i] = xs[contacts[i]]
        gy[i] = 0.0
    for g in range(ptr.size - 1):
        if ptr[g + 1] > ptr[g]:
            packed_times(wval[woff[g]:woff[g + 1]], ptr[g + 1] - ptr[g], gx[ptr[g]:ptr[g + 1]],
                         gy[ptr[g]:ptr[g + 1]])
    for i in range(gy.size):
        out[contacts[i]] += gy[i]
    for c in range(nc):
        out[c] *= s[c]


@numba.njit(cache=True)
def _work(op, nc):
    """The work arrays of :func:`_times` for ``op`` and ``nc`` contacts: xs (nc,); hx (n packed
    dofs,) zero, vx (n,); gx, gy (contacts of the W_G,); the rows' entries applied through the
    compliance, contact c's at eptr[c]:eptr[c + 1] (eptr (nc + 1,)) with their dofs ``edof``
    and values ``eh`` of H_n; the 1x1-block dofs they touch ``diag_dofs`` and the compliance
    blocks ``blocks`` (the others are not touched: no product with them). Made once per solve,
    so that a product reads each entry's route from one list instead of the dofs' blocks."""
    dof, hn, diagonal, block, dense = op[0], op[1], op[2], op[3], op[7]
    m = dof.shape[1]
    n = diagonal.size
    eptr = np.zeros(nc + 1, np.int64)
    edof = np.empty(nc * m, np.int64)  # at most every entry; the list's end is eptr[nc]
    eh = np.empty(nc * m)
    seen_dof = np.zeros(n, np.bool_)
    seen_block = np.zeros(dense.size, np.bool_)
    e = 0
    for c in range(nc):
        for a in range(m):
            d = dof[c, a]
            if d >= 0 and (block[d] < 0 or not dense[block[d]]):
                edof[e] = d
                eh[e] = hn[c, a]
                e += 1
                if block[d] < 0:
                    seen_dof[d] = True
                else:
                    seen_block[block[d]] = True
        eptr[c + 1] = e
    nd = op[9].size  # the contacts of the blocks with their W_G
    return (np.empty(nc), np.zeros(n), np.empty(n), np.empty(nd), np.empty(nd), eptr, edof, eh,
            np.flatnonzero(seen_dof), np.flatnonzero(seen_block))


@numba.njit(cache=True)
def _error(kind, tol, bound, wnn, rho, s, y, g, q):
    """The measure's error (:func:`compute.contact.residual.local_contact_error`) of the scaled
    iterate y (nc,) with scaled gradient g (nc,): the impulses r_n = s y, ũ_n = g / s, no
    tangential part; ``rho`` (nc,) 1 / W_nn,c (1 where W_nn,c = 0); one pass, nothing stored."""
    sums = (0.0, 0.0, 0.0, 0.0, 0.0)
    for c in range(y.size):
        un = g[c] / s[c]
        rn = s[c] * y[c]
        e2 = squared_normal_error(rho[c], un, rn, abs(q[c, 0]) + abs(un) + abs(q[c, 1]))
        w = un - q[c, 0]
        sums = add_contact(kind, sums, e2, wnn[c], rn * rn, w * w, un)
    return error_of_sums(kind, tol, bound, sums)


@numba.njit(cache=True)
def mprgp(op, wnn, q, r, kind, tol, bound, max_iterations):
    """Minimise ½ r_nᵀ W_nn r_n + q_nᵀ r_n over r_n ≥ 0 (module docstring), in place.

    ``op`` W_nn (:func:`_times`): the packed normal rows ``dof``, ``hn`` (nc, m) of H, the
    compliance arrays (:meth:`compute.contact.compliance.Compliance.arrays`) and the soft bodies'
    blocks of W_nn (:func:`compute.contact.delassus.normal_groups`); ``wnn``
    (nc,) the diagonal of W_nn;
    ``q`` (nc, 2) the local free velocities (ũ_n, u_t at r = 0); ``r`` (nc, 2) the warm start in
    (r_n used, projected on r_n ≥ 0), the solution out (r_t = 0); (kind, tol, bound) the error
    measure. Returns the iterations (one product with W each, a redone expansion's left out)."""
    nc = q.shape[0]
    work = _work(op, nc)
    s = np.empty(nc)
    rho = np.empty(nc)  # the natural map's scale 1 / W_nn,c (compute.contact.residual)
    for c in range(nc):
        s[c] = 1.0 / np.sqrt(wnn[c]) if wnn[c] > 0.0 else 1.0
        rho[c] = 1.0 / wnn[c] if wnn[c] > 0.0 else 1.0
    b = np.empty(nc)  # the scaled q_n
    y = np.empty(nc)
    for c in range(nc):
        b[c] = s[c] * q[c, 0]
        y[c] = max(r[c, 0], 0.0) / s[c]
    g = np.empty(nc)
    _times(op, s, y, work, g)
    g += b
    if _error(kind, tol, bound, wnn, rho, s, y, g, q) <= tol or max_iterations <= 0:
        _unscaled(s, y, r)  # the warm start solves it, judged on the exact g
        return 0
    ap = np.empty(nc)
    norm = 1.0  # the largest curvature met, a lower bound of ‖S W S‖ (unit diagonal: at least 1)
    alpha_bar = EXPANSION / norm
    p = np.zeros(nc)
    y_half = np.empty(nc)
    g_half = np.empty(nc)
    d = np.empty(nc)
    for c in range(nc):
        p[c] = g[c] if y[c] > 0.0 else 0.0
    iterations = 0
    while True:
        if _error(kind, tol, bound, wnn, rho, s, y, g, q) <= tol:
            _times(op, s, y, work, g)  # judge the exact g
            g += b
            if _error(kind, tol, bound, wnn, rho, s, y, g, q) <= tol or iterations >= max_iterations:
                break
        if iterations >= max_iterations:
            break
        iterations += 1
        beta2 = 0.0
        phi_tilde_phi = 0.0
        for c in range(nc):
            if y[c] > 0.0:
                phi_tilde_phi += min(y[c] / alpha_bar, g[c]) * g[c]
            elif g[c] < 0.0:
                beta2 += g[c] * g[c]
        if beta2 <= GAMMA * GAMMA * phi_tilde_phi:
            _times(op, s, p, work, ap)
            pap = dot(p, ap)
            norm, alpha_bar = _curvature(norm, alpha_bar, pap, dot(p, p))
            alpha_cg = dot(g, p) / pap if pap > 0.0 else np.inf  # inf: p in W's null space
            alpha_f = np.inf
            for c in range(nc):
                if p[c] > 0.0:
                    alpha_f = min(alpha_f, y[c] / p[c])
            if alpha_f == np.inf and alpha_cg == np.inf:  # unbounded: no solution (overlaps no velocity removes)
                break
            if alpha_cg <= alpha_f:  # conjugate gradient step
                for c in range(nc):
                    y[c] = max(y[c] - alpha_cg * p[c], 0.0)  # >= 0 but for rounding at alpha_cg = alpha_f
                    g[c] -= alpha_cg * ap[c]
                num = 0.0
                for c in range(nc):
                    if y[c] > 0.0:
                        num += g[c] * ap[c]
                gamma = num / pap
                for c in range(nc):
                    p[c] = (g[c] if y[c] > 0.0 else 0.0) - gamma * p[c]
            else:  # expansion: to the boundary, then a projected free-gradient step
                for c in range(nc):
                    y_half[c] = max(y[c] - alpha_f * p[c], 0.0)
                    g_half[c] = g[c] - alpha_f * ap[c]
                while True:
                    for c in range(nc):
                        y[c] = max(y_half[c] - alpha_bar * g_half[c], 0.0) if y_half[c] > 0.0 else 0.0
                    _times(op, s, y, work, g)
                    g += b
                    dd = 0.0
                    dad = 0.0
                    for c in range(nc):
                        dd += (y[c] - y_half[c]) ** 2
                        dad += (y[c] - y_half[c]) * (g[c] - g_half[c])
                    if alpha_bar * dad <= 2.0 * dd:  # within the curvature bound: the step descends
                        break
                    known = norm
                    norm, alpha_bar = _curvature(norm, alpha_bar, dad, dd)  # ᾱ too long: redo it shorter
                    if norm == known:  # nothing learnt (non-finite values): keep the step, the stop test judges
                        break
                for c in range(nc):
                    p[c] = g[c] if y[c] > 0.0 else 0.0
        else:  # proportioning: release contacts along the chopped gradient
            for c in range(nc):
                d[c] = g[c] if y[c] <= 0.0 and g[c] < 0.0 else 0.0
            _times(op, s, d, work, ap)
            dad = dot(d, ap)
            if dad <= 0.0:
                break
            norm, alpha_bar = _curvature(norm, alpha_bar, dad, dot(d, d))
            alpha = dot(g, d) / dad
            for c in range(nc):
                y[c] -= alpha * d[c]
                g[c] -= alpha * ap[c]
            for c in range(nc):
                p[c] = g[c] if y[c] > 0.0 else 0.0
    _unscaled(s, y, r)
    return iterations


@numba.njit(cache=True)
def _curvature(norm, alpha_bar, dad, dd):
    """(λ, ᾱ) after a direction d of curvature dᵀAd / dᵀd = ``dad`` / ``dd`` was met: λ the
    largest curvature so far (a lower bound of ‖A‖), ᾱ = EXPANSION / λ."""
    if dd > 0.0 and dad > norm * dd:
        norm = dad / dd
        return norm, EXPANSION / norm
    return norm, alpha_bar


@numba.njit(cache=True)
def _unscaled(s, y, r):
    """The impulses r (nc, 2) = (s y, 0) of the scaled iterate y (nc,)."""
    for c in range(y.size):
        r[c, 0] = s[c] * y[c]
        r[c, 1] = 0.0
