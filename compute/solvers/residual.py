r"""The true error of a 2D frictional contact solution: the natural map of the Signorini–Coulomb law.

For contact c with impulse r = (r_n, r_t), local velocity u = (ũ_n, u_t) (ũ_n = u_n + g̃ / (h θ),
see :mod:`compute.contact.problem`) and friction coefficient μ, the law (Signorini on ũ_n,
Coulomb on (r, u_t)) holds if and only if (De Saxcé's bipotential form)

    f_c = r - P_K(r - ρ_c ū) = 0,      ū = (ũ_n + μ |u_t|, u_t),      K = {|r_t| ≤ μ r_n},

P_K the projection on the (2D, polyhedral) Coulomb cone and ρ_c > 0 any scale; ρ_c = 1 / W_nn,c
makes ρ ū an impulse. The error of a solution is ‖f‖ / ‖r‖ over all contacts (2-norms): it is
zero exactly at a solution, and unlike the change of r between two Gauss–Seidel sweeps it does
not understate the error where the iteration converges slowly. Being one norm over all contacts, it
bounds the violation of the packing, not of each contact: in a 144-disk T3 mixture at P/E = 1
(about 1100 active contacts) 36 rigid-disk-against-segment rows stay 1–2.5e-3 inside from step
to step at a tolerance of 1e-4 and are pushed out at 1e-6 (benchmarks/experiments/README.md).
"""

from __future__ import annotations

import numba
import numpy as np

ROUNDING = 1e-13


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
def natural_map_error(dof, hn, ht, W, gap_term, mu, r, v):
    """‖f‖ / ‖r‖ (module docstring) of impulses r (nc, 2) with velocities v (n_dofs,)
    = v_free + M̂⁻¹ H r; rows of H ``dof``, ``hn``, ``ht`` (nc, m), ``W`` (nc, 2, 2),
    ``gap_term`` (nc,), ``mu`` (nc,). 0 for no contact or r = 0 with every contact open; inf for
    r = 0 with some contact closing; f at rounding level counts as 0 (``squared_error``)."""
    num = 0.0
    den = 0.0
    for c in range(dof.shape[0]):
        un, ut, size = contact_velocity(dof, hn, ht, gap_term[c], v, c)
        num += squared_error(W[c, 0, 0], un, ut, r[c, 0], r[c, 1], mu[c], size)
        den += r[c, 0] * r[c, 0] + r[c, 1] * r[c, 1]
    return relative(num, den)


@numba.njit(cache=True)
def velocity_error(dof, hn, ht, W, gap_term, mu, r, v, v_free):
    r"""The natural-map error in velocity units: per contact e_c = W_nn,c f_c (f_c with
    ρ_c = 1 / W_nn,c, so that e_c is the velocity error of contact c whatever its compliance),
    relative to the velocities the impulses make, w_c = H_cᵀ (v - v_free) (= (W r)_c).
    Returns (‖e‖ / ‖w‖ over all contacts (2-norms), max_c |e_c| / max_c |w_c|): the first
    bounds the packing's error, the second every contact's. Arrays as in
    ``natural_map_error``, ``v_free`` (n_dofs,) packed like v."""
    num = 0.0
    den = 0.0
    top = 0.0
    scale = 0.0
    dv = v - v_free
    for c in range(dof.shape[0]):
        un, ut, size = contact_velocity(dof, hn, ht, gap_term[c], v, c)
        wn, wt, _ = contact_velocity(dof, hn, ht, 0.0, dv, c)
        wnn = W[c, 0, 0] if W[c, 0, 0] > 0.0 else 1.0
        e2 = squared_error(W[c, 0, 0], un, ut, r[c, 0], r[c, 1], mu[c], size) * wnn * wnn
        w2 = wn * wn + wt * wt
        num += e2
        den += w2
        top = max(top, e2)
        scale = max(scale, w2)
    return relative(num, den), relative(top, scale)
