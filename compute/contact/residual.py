r"""The true error of a 2D frictional contact solution: the natural map of the Signorini–Coulomb law.

For contact c with impulse r = (r_n, r_t), local velocity u = (ũ_n, u_t) (ũ_n = u_n + g̃ / (h θ),
see :mod:`compute.contact.problem`) and friction coefficient μ, the law (Signorini on ũ_n,
Coulomb on (r, u_t)) holds if and only if (De Saxcé's bipotential form)

    f_c = r - P_K(r - ρ_c ū) = 0,      ū = (ũ_n + μ |u_t|, u_t),      K = {|r_t| ≤ μ r_n},

P_K the projection on the (2D, polyhedral) Coulomb cone and ρ_c > 0 any scale; ρ_c = 1 / W_nn,c
makes ρ ū an impulse. The error of a solution is ‖f‖ / ‖r‖ over all contacts (2-norms): it is
zero exactly at a solution, and unlike the change of r between two Gauss–Seidel sweeps it does
not understate the error where the iteration converges slowly. Being one norm over all contacts, it
bounds the violation of the packing, not of each contact: among the many active contacts of a
large mixture a few rows can stay inside, from step to step, by more than the tolerance suggests,
and a tighter tolerance pushes them out (benchmarks/experiments/README.md, segment-disk rows).

Measures (:class:`Measure`, a scene's ``solver.contact_error``):

- ``"impulse"``: ‖f‖ / ‖r‖, f with ρ_c = 1 / W_nn,c. It weights each contact's velocity error by
  1 / W_nn,c, so it understates the error of compliant contacts (a soft body's node, W_nn up to
  hundreds of times a rigid disk's) and of a static packing, whose impulses are large against
  the velocities they make.
- ``"velocity"``: the same f in velocity units, e_c = W_nn,c f_c (the projection is positively
  homogeneous, so e_c is the error of contact c's velocity whatever its compliance), relative to
  the velocities the impulses make, w_c = (W r)_c = H_cᵀ (v - v_free): ‖e‖ / ‖w‖ over the packing.
- ``"velocity_max"``: max_c |e_c| / max_c |w_c|, which holds every contact, not the packing's
  mean.

A penetration bound δ (a length, ``Measure.penetration``) adds the test that no contact's
predicted end-of-step gap g̃ + h θ u_n is below -δ: the error reported is then
max(error, tolerance · overlap / δ), at most the tolerance exactly when both hold, so every
solver and the Newton loop keep one number to stop on and to report.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

ROUNDING = 1e-13

IMPULSE, VELOCITY, VELOCITY_MAX = 0, 1, 2  # the measures of ``Measure.kind``, as the kernels take them
KINDS = {"impulse": IMPULSE, "velocity": VELOCITY, "velocity_max": VELOCITY_MAX}


@numba.njit(cache=True, inline="always")
def project_cone(xn, xt, mu):
    """P_K(x_n, x_t) on K = {|x_t| <= mu x_n} (mu >= 0)."""
    if xn >= 0.0 and abs(xt) <= mu * xn:
        return xn, xt
    if mu * abs(xt) <= -xn:  # the polar cone
        return 0.0, 0.0
    s = 1.0 if xt > 0.0 else -1.0
    a = (xn + mu * abs(xt)) / (1.0 + mu * mu)
    return a, s * mu * a


@numba.njit(cache=True, inline="always")
def local_error(wnn, un, ut, rn, rt, mu):
    """(f_n, f_t) of one contact (module docstring), ρ = 1 / wnn (1 for a contact between two
    immovable bodies, wnn = 0)."""
    rho = 1.0 / wnn if wnn > 0.0 else 1.0
    pn, pt = project_cone(rn - rho * (un + mu * abs(ut)), rt - rho * ut, mu)
    return rn - pn, rt - pt


@numba.njit(cache=True, inline="always")
def squared_error(wnn, un, ut, rn, rt, mu, size):
    """|f|² of one contact (``local_error``), 0 when f is below ``ROUNDING`` times the magnitude of
    the numbers it is computed from: ``size`` the sum of the magnitudes of the terms of u (a
    touching contact at rest has u at rounding level, and f with it)."""
    fn, ft = local_error(wnn, un, ut, rn, rt, mu)
    rho = 1.0 / wnn if wnn > 0.0 else 1.0
    if abs(fn) + abs(ft) <= ROUNDING * (rho * size + abs(rn) + abs(rt)):
        return 0.0
    return fn * fn + ft * ft


@numba.njit(cache=True, inline="always")
def squared_normal_error(rho, un, rn, size):
    """``squared_error`` of a contact without friction and without tangential parts (μ = 0,
    u_t = r_t = 0), ρ = 1 / W_nn,c given: the cone is the half-line r_n ≥ 0, so
    f_n = r_n - max(r_n - ρ ũ_n, 0); the same number, without the division and the cone's
    branches (MPRGP evaluates it at every iteration)."""
    xn = rn - rho * un
    fn = rn - (0.0 if xn < 0.0 else xn)  # a NaN goes through, as in project_cone
    return 0.0 if abs(fn) <= ROUNDING * (rho * size + abs(rn)) else fn * fn


@numba.njit(cache=True, inline="always")
def relative(num, den):
    """sqrt(Σ|f|² / Σ|r|²): 0 when every f is 0, inf when r = 0 but some f is not."""
    if num == 0.0:
        return 0.0
    return np.sqrt(num / den) if den > 0.0 else np.inf


@numba.njit(cache=True, inline="always")
def contact_velocity(dof, hn, ht, gap_term_c, v, c):
    """(ũ_n, u_t, size) of contact c: H_cᵀ v plus its gap term, and the sum of the magnitudes of
    the terms (``squared_error``'s rounding scale)."""
    un = gap_term_c
    ut = 0.0
    size = abs(gap_term_c)
    for k in range(dof.shape[1]):
        d = dof[c, k]
        if d >= 0:
            un += hn[c, k] * v[d]
            ut += ht[c, k] * v[d]
            size += abs(hn[c, k] * v[d]) + abs(ht[c, k] * v[d])
    return un, ut, size


@numba.njit(cache=True)
def local_contact_error(kind, tol, bound, wnn, u, w, r, mu, size):
    """The error of ``kind`` (IMPULSE, VELOCITY, VELOCITY_MAX, module docstring) from per-contact
    arrays: ``wnn`` (nc,) W_nn,c, ``u`` (nc, 2) (ũ_n, u_t), ``w`` (nc, 2) (W r)_c (unused for
    IMPULSE), ``r`` (nc, 2), ``mu`` (nc,), ``size`` (nc,) the rounding scale of u
    (``squared_error``). With ``bound`` > 0 (an overlap in velocity units, δ / (h θ)) the
    penetration test is folded in: max(error, tol · max_c(-ũ_n,c) / bound)."""
    sums = (0.0, 0.0, 0.0, 0.0, 0.0)
    for c in range(u.shape[0]):
        e2 = squared_error(wnn[c], u[c, 0], u[c, 1], r[c, 0], r[c, 1], mu[c], size[c])
        sums = add_contact(kind, sums, e2, wnn[c], r[c, 0] * r[c, 0] + r[c, 1] * r[c, 1],
                           w[c, 0] * w[c, 0] + w[c, 1] * w[c, 1], u[c, 0])
    return error_of_sums(kind, tol, bound, sums)


@numba.njit(cache=True, inline="always")
def add_contact(kind, sums, e2, wnn, r2, w2, un):
    """``sums`` (Σ|f|², Σ|r|² or Σ|w|², max |e|², max |w|², max -ũ_n) with one contact added: its
    |f_c|² ``e2`` (``squared_error``), W_nn,c, |r_c|², |w_c|² and ũ_n,c (``local_contact_error``)."""
    num, den, top, scale, overlap = sums
    if kind == IMPULSE:
        num += e2
        den += r2
    else:
        s = wnn if wnn > 0.0 else 1.0
        e2 *= s * s
        num += e2
        den += w2
        top = max(top, e2)
        scale = max(scale, w2)
    return num, den, top, scale, max(overlap, -un)


@numba.njit(cache=True, inline="always")
def error_of_sums(kind, tol, bound, sums):
    """The error of ``kind`` from the ``sums`` of ``add_contact``, the penetration test folded in
    (``local_contact_error``)."""
    num, den, top, scale, overlap = sums
    error = relative(top, scale) if kind == VELOCITY_MAX else relative(num, den)
    if bound > 0.0 and overlap > bound:
        error = max(error, tol * overlap / bound)
    return error


@numba.njit(cache=True)
def contact_error(kind, tol, bound, dof, hn, ht, W, gap_term, mu, r, v, v_free):
    """``local_contact_error`` of impulses r (nc, 2) with velocities v (n_dofs,)
    = v_free + M̂⁻¹ H r; rows of H ``dof``, ``hn``, ``ht`` (nc, m), ``W`` (nc, 2, 2), ``gap_term``
    (nc,), ``mu`` (nc,), ``v_free`` (n_dofs,) packed like v. 0 for no contact or r = 0 with every
    contact open; inf for r = 0 with some contact closing; f at rounding level counts as 0."""
    nc = dof.shape[0]
    u = np.empty((nc, 2))
    w = np.zeros((nc, 2))
    size = np.empty(nc)
    wnn = np.empty(nc)
    for c in range(nc):
        u[c, 0], u[c, 1], size[c] = contact_velocity(dof, hn, ht, gap_term[c], v, c)
        if kind != IMPULSE:  # w = Hᵀ (v - v_free): u less its gap term, less the free velocity's
            fn, ft, _ = contact_velocity(dof, hn, ht, 0.0, v_free, c)
            w[c, 0], w[c, 1] = u[c, 0] - gap_term[c] - fn, u[c, 1] - ft
        wnn[c] = W[c, 0, 0]
    return local_contact_error(kind, tol, bound, wnn, u, w, r, mu, size)


@numba.njit(cache=True)
def natural_map_error(dof, hn, ht, W, gap_term, mu, r, v):
    """‖f‖ / ‖r‖ (the ``"impulse"`` measure) of impulses r (nc, 2) with velocities v (n_dofs,);
    arrays as in ``contact_error``."""
    return contact_error(IMPULSE, 0.0, 0.0, dof, hn, ht, W, gap_term, mu, r, v, v)


@numba.njit(cache=True)
def velocity_error(dof, hn, ht, W, gap_term, mu, r, v, v_free):
    """(``"velocity"``, ``"velocity_max"``) errors of impulses r (nc, 2) with velocities v
    (n_dofs,): the packing's and the worst contact's; arrays as in ``contact_error``."""
    return (contact_error(VELOCITY, 0.0, 0.0, dof, hn, ht, W, gap_term, mu, r, v, v_free),
            contact_error(VELOCITY_MAX, 0.0, 0.0, dof, hn, ht, W, gap_term, mu, r, v, v_free))


@dataclass(frozen=True)
class Measure:
    """What a contact solve's error is (module docstring): ``kind`` one of ``KINDS``;
    ``penetration`` δ, a length (0: no penetration test)."""

    kind: str = "impulse"
    penetration: float = 0.0

    def codes(self, problem, tol: float) -> tuple[int, float, float]:
        """(kind, tol, bound) as the kernels take them, for ``problem`` (a ContactProblem): the
        bound δ / (h θ) in velocity units, 0 without a penetration test."""
        bound = self.penetration / problem.h_theta if self.penetration > 0.0 else 0.0
        return KINDS[self.kind], tol, bound

    def error(self, problem, tol: float, v: np.ndarray) -> float:
        """The error of ``problem``'s impulses with velocities v (n_dofs,)."""
        o = problem.compliance.order
        return contact_error(*self.codes(problem, tol), problem.dof, problem.hn, problem.ht, problem.W,
                             problem.gap_term, problem.mu, problem.impulse, v[o], problem.v_free[o])
