r"""Block Gauss–Seidel: the contacts of one dense compliance block (one soft body) solved exactly
together, by a semismooth Newton method on the Alart–Curnier function; Gauss–Seidel over these
blocks and the remaining single contacts (rigid bodies, walls).

Why: the contacts of one soft body are coupled through its compliance M̂_b⁻¹, strongly: the
point Gauss–Seidel of :mod:`compute.solvers.nlgs` contracts slowly there (hundreds of sweeps per
solve; benchmarks/results/design_figures.md), while a Newton method on the block converges in
a few iterations.

Blocks: a contact belongs to the dense compliance block of the first of its dofs that lies in
one (the node side of a node–segment contact); contacts without such a dof are single blocks,
solved by the exact local 2D solution of the NLGS. For block B with k contacts,
u_B = W_BB r_B + b_B, W_BB (2k, 2k) = H_Bᵀ M̂⁻¹ H_B (all dofs of its contacts, other bodies'
included), b_B the local velocities of the other impulses.

Alart–Curnier, per contact (ρ = 1 / W_nn, τ_n = r_n - ρ ũ_n, τ_t = r_t - ρ u_t):

    Φ_n = r_n - max(0, τ_n),     Φ_t = r_t - proj_[-μ max(0, τ_n), μ max(0, τ_n)](τ_t),

Φ = 0 exactly at a solution of the Signorini–Coulomb law. Newton steps on the generalised
Jacobian (open: Φ = r; closed: Φ_n = ρ ũ_n; stick: Φ_t = ρ u_t; slip: Φ_t = r_t - μ τ_n sgn τ_t;
frictionless: Φ_t = r_t), with a backtracking line search on |Φ|² (least squares where the
Jacobian is singular: redundant contacts). A block the Newton method does not settle in
``BLOCK_ITERATIONS`` falls back to point Gauss–Seidel sweeps on its contacts.

Stopping: the natural-map error of all contacts (:mod:`compute.contact.residual`) at most
``tolerance``, checked after every sweep. A problem of one block stops after one sweep whatever
its error (its block solve was the whole solve: repeating a failed one would not help, and each
costs up to BLOCK_ITERATIONS Newton steps and FALLBACK_SWEEPS point sweeps); a miss shows as
an error above tolerance. With ``stall_window`` > 0 it also stops, above tolerance, when the
error checked every stall_window sweeps stops falling or falls too slowly to reach the tolerance
within ``projected_limit`` sweeps (the NLGS stall test, :func:`compute.solvers.nlgs.stalled`).
Why: as the fallback of a stalled NLGS (:mod:`compute.solvers.nlgs_then`) on a packing of finely
meshed soft disks at high pressure, block Gauss–Seidel can creep towards the tolerance for
hundreds of sweeps, each costing as much as a hundred or more point sweeps: given NLGS's budget
of sweeps, one contact solve ran for most of an hour. A stalled solve ends as a miss, which the
next Newton iteration and the step control absorb (benchmarks/results/block_gs_stall.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from compute.contact.compliance import add_contact_impulse, block_delassus
from compute.contact.rows import local_velocity
from compute.fixed_order import dot, matvec
from compute.solvers.report import SolveReport
from compute.solvers.nlgs import apply_impulses, local_signorini_coulomb, stalled
from compute.contact.residual import Measure, contact_error, relative, squared_error

BLOCK_ITERATIONS = 30
FALLBACK_SWEEPS = 200


@dataclass(frozen=True)
class BlockGS:
    """Block Gauss–Seidel (module docstring): stops when the natural-map error is at most
    ``tolerance``, after ``max_sweeps`` sweeps over the blocks, or, with ``stall_window`` > 0,
    when it stalls."""

    tolerance: float
    max_sweeps: int
    measure: Measure = Measure()
    stall_window: int = 0  # sweeps between stall checks (0: none)
    projected_limit: int = 0  # with stall_window: also stalled when the tolerance is this many sweeps away

    def solve(self, problem) -> SolveReport:
        """Solve ``problem`` (a ContactProblem) from its warm-start impulses, in place."""
        carr = problem.compliance.arrays()
        order, bstart = blocks_of(problem.dof, problem.compliance.block)
        wb, woff = block_delassus(order, bstart, problem.dof, problem.hn, problem.ht, *carr)
        v_free = problem.free_velocity()
        v = v_free.copy()
        apply_impulses(problem.dof, problem.hn, problem.ht, problem.impulse, v, *carr)
        sweeps, error = block_gs_solve(order, bstart, wb, woff, problem.dof, problem.hn, problem.ht, problem.W,
                                       problem.gap_term, problem.mu, problem.impulse, v, v_free, *carr,
                                       *self.measure.codes(problem, self.tolerance), self.max_sweeps,
                                       self.stall_window, self.projected_limit)
        return SolveReport(problem.velocities(v), sweeps, error)


def blocks_of(dof: np.ndarray, block: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """ContactRows grouped by block: ``order`` (nc,) contact indices, block after block, and
    ``bstart`` (n_blocks + 1,) offsets into it. A contact's block is the dense compliance block
    of its first dof in one (``block`` (n_dofs,), -1: none); others are blocks of one."""
    nc = dof.shape[0]
    if nc == 0:
        return np.zeros(0, np.int64), np.zeros(1, np.int64)
    b = np.where(dof >= 0, block[np.maximum(dof, 0)], -1)  # (nc, m)
    has = b >= 0
    first = np.where(has.any(axis=1), b[np.arange(nc), np.argmax(has, axis=1)], -1)
    key = np.where(first >= 0, first, first.max(initial=-1) + 1 + np.arange(nc))  # singletons last, own keys
    order = np.argsort(key, kind="stable").astype(np.int64)
    ks = key[order]
    bstart = np.concatenate([[0], np.flatnonzero(np.diff(ks)) + 1, [nc]]).astype(np.int64)
    return order, bstart


@numba.njit(cache=True)
def _phi_and_jacobian(W, b, mu, r, phi, J):
    """Alart–Curnier Φ (2k,) and a generalised Jacobian J (2k, 2k) at r (2k,), u = W r + b.
    Returns |Φ|²."""
    n2 = r.shape[0]
    u = matvec(W, r) + b
    J[:, :] = 0.0
    total = 0.0
    for c in range(n2 // 2):
        i, t = 2 * c, 2 * c + 1
        rho = 1.0 / W[i, i] if W[i, i] > 0.0 else 1.0
        tau_n = r[i] - rho * u[i]
        tau_t = r[t] - rho * u[t]
        if tau_n <= 0.0:  # open
            phi[i], phi[t] = r[i], r[t]
            J[i, i] = 1.0
            J[t, t] = 1.0
        else:
            phi[i] = rho * u[i]
            J[i, :] = rho * W[i, :]
            bound = mu[c] * tau_n
            if mu[c] == 0.0:  # frictionless: r_t = 0 (its row of W may be zero, node–wall)
                phi[t] = r[t]
                J[t, t] = 1.0
            elif abs(tau_t) <= bound:  # stick
                phi[t] = rho * u[t]
                J[t, :] = rho * W[t, :]
            else:  # slip
                s = 1.0 if tau_t > 0.0 else -1.0
                phi[t] = r[t] - s * bound
                J[t, :] = s * mu[c] * rho * W[i, :]
                J[t, t] += 1.0
                J[t, i] -= s * mu[c]
        total += phi[i] * phi[i] + phi[t] * phi[t]
    return total


@numba.njit(cache=True)
def _lu_solve(A, b):
    """x (n,) with A x = b by Gaussian elimination with partial pivoting, and whether A was
    regular (a pivot below 1e-14 of A's largest entry means singular). A, b are not changed."""
    n = b.shape[0]
    a = A.copy()
    x = b.copy()
    small = 1e-14 * max(np.abs(a).max(), 1e-300)
    for k in range(n):
        p = k + np.argmax(np.abs(a[k:, k]))
        if abs(a[p, k]) <= small:
            return x, False
        if p != k:
            for j in range(n):
                a[k, j], a[p, j] = a[p, j], a[k, j]
            x[k], x[p] = x[p], x[k]
        for i in range(k + 1, n):
            f = a[i, k] / a[k, k]
            if f != 0.0:
                a[i, k:] -= f * a[k, k:]
                x[i] -= f * x[k]
    for k in range(n - 1, -1, -1):
        x[k] = (x[k] - dot(a[k, k + 1:], x[k + 1:])) / a[k, k]
    return x, True


@numba.njit(cache=True)
def _block_error(W, b, mu, r):
    """Natural-map error ‖f‖ / ‖r‖ of the block alone (compute.contact.residual)."""
    u = matvec(W, r) + b
    size = matvec(np.abs(W), np.abs(r)) + np.abs(b)  # magnitudes of the terms of u
    num = 0.0
    den = 0.0
    for c in range(r.shape[0] // 2):
        i, t = 2 * c, 2 * c + 1
        num += squared_error(W[i, i], u[i], u[t], r[i], r[t], mu[c], size[i] + size[t])
        den += r[i] ** 2 + r[t] ** 2
    return relative(num, den)


@numba.njit(cache=True)
def solve_block(W, b, mu, r, tol):
    """Impulses r (2k,) (in: warm start, out: solution) of u = W r + b with the Signorini–Coulomb
    law, by semismooth Newton (module docstring), point Gauss–Seidel if that does not settle.
    Returns the block's natural-map error."""
    n2 = r.shape[0]
    phi = np.zeros(n2)
    J = np.zeros((n2, n2))
    trial = np.zeros(n2)
    phi_t = np.zeros(n2)
    J_t = np.zeros((n2, n2))
    for _ in range(BLOCK_ITERATIONS):
        err = _block_error(W, b, mu, r)
        if err <= tol:
            return err
        f0 = _phi_and_jacobian(W, b, mu, r, phi, J)
        step, ok = _lu_solve(J, -phi)
        if not ok:  # singular generalised Jacobian (redundant contacts): least squares
            step = np.linalg.lstsq(J, -phi, 1e-12)[0]
        a = 1.0
        for _ls in range(20):
            trial[:] = r + a * step
            if _phi_and_jacobian(W, b, mu, trial, phi_t, J_t) <= (1.0 - 1e-4 * a) * f0:
                break
            a *= 0.5
        r[:] = trial
    err = _block_error(W, b, mu, r)
    if err <= tol:
        return err
    for _ in range(FALLBACK_SWEEPS):  # point Gauss–Seidel on the block
        u = matvec(W, r) + b
        for c in range(n2 // 2):
            i, t = 2 * c, 2 * c + 1
            un = u[i] - W[i, i] * r[i] - W[i, t] * r[t]
            ut = u[t] - W[t, i] * r[i] - W[t, t] * r[t]
            rn, rt = local_signorini_coulomb(W[i, i], W[i, t], W[t, i], W[t, t], un, ut, mu[c])
            dn, dt = rn - r[i], rt - r[t]
            r[i], r[t] = rn, rt
            u += W[:, i] * dn + W[:, t] * dt
        err = _block_error(W, b, mu, r)
        if err <= tol:
            break
    return err


@numba.njit(cache=True)
def block_gs_solve(order, bstart, wb, woff, dof, hn, ht, W, gap_term, mu, r, v, v_free, diagonal, block, start,
                   offset, values, kind, tol, bound, max_sweeps, stall_window, projected_limit):
    """Solve the contact problem in place (module docstring); rows over packed dofs, v (n,)
    packed velocities that include the warm-start impulses, ``v_free`` (n,); the error measure
    (kind, tol, bound) of :meth:`compute.contact.residual.Measure.codes`. Returns (sweeps, error)."""
    nb = bstart.shape[0] - 1
    error = contact_error(kind, tol, bound, dof, hn, ht, W, gap_term, mu, r, v, v_free)
    if error <= tol:
        return 0, error
    best = np.inf  # the last stall check's error
    for sweep in range(1, max_sweeps + 1):
        for B in range(nb):
            k = bstart[B + 1] - bstart[B]
            n2 = 2 * k
            Wb = wb[woff[B]:woff[B + 1]].reshape(n2, n2)
            rb = np.empty(n2)
            mub = np.empty(k)
            u = np.empty(n2)
            for i in range(k):
                c = order[bstart[B] + i]
                rb[2 * i], rb[2 * i + 1] = r[c, 0], r[c, 1]
                mub[i] = mu[c]
                un, ut = local_velocity(dof, hn, ht, c, v)
                u[2 * i], u[2 * i + 1] = un + gap_term[c], ut
            bb = u - matvec(Wb, rb)
            r0 = rb.copy()
            if k == 1:
                rn, rt = local_signorini_coulomb(Wb[0, 0], Wb[0, 1], Wb[1, 0], Wb[1, 1], bb[0], bb[1], mub[0])
                rb[0], rb[1] = rn, rt
            else:
                solve_block(Wb, bb, mub, rb, 0.1 * tol)
            for i in range(k):
                c = order[bstart[B] + i]
                dn, dt = rb[2 * i] - r0[2 * i], rb[2 * i + 1] - r0[2 * i + 1]
                if dn == 0.0 and dt == 0.0:
                    continue
                r[c, 0], r[c, 1] = rb[2 * i], rb[2 * i + 1]
                add_contact_impulse(v, c, dn, dt, dof, hn, ht, diagonal, block, start, offset, values)
        error = contact_error(kind, tol, bound, dof, hn, ht, W, gap_term, mu, r, v, v_free)
        if error <= tol or nb == 1:  # one block: its solve was the whole solve
            return sweep, error
        if stall_window > 0 and sweep % stall_window == 0 and sweep < max_sweeps:
            if stalled(error, best, tol, stall_window, projected_limit, max_sweeps - sweep):
                return sweep, error
            best = error
    return max_sweeps, error
