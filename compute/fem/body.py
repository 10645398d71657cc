r"""Total-Lagrangian finite elements for one deformable body (plane strain, unit thickness).

Conventions. Reference positions X and current positions x are (n_nodes, 2) arrays; every nodal
vector (forces, velocities, residuals) is flat, (2 n_nodes,), in the dof order
[x0, y0, x1, y1, ...], i.e. ``x.reshape(-1)``. Sparse matrices are scipy CSR, (2n, 2n), and all
share one sparsity pattern (every dof pair of every element, explicit zeros included), so that
M + c K_t is a single vector operation on ``.data``.

Discrete strain energy, with w_q = (reference weight x reference Jacobian) at the quadrature
points of the element's stiffness rule and F_q = sum_a x_a (x) dN_a/dX:

    E(x) = sum_e sum_q w_q W_iso(F_q) + E_vol,
    standard:         E_vol = sum_e sum_q w_q U(J_q)
    mean_dilatation:  E_vol = sum_e V_e U(v_e / V_e),  V_e = sum_q w_q,  v_e = sum_q w_q J_q

f_int = dE/dx and K_t = d f_int/dx exactly (the tangent is consistent with the quadrature).
The isochoric part gives f_ai = sum_q w P_iJ dN_aJ and K_aibk = sum_q w dN_aJ A_iJkL dN_bL.
Both volumetric variants are one formula, applied per quadrature point (V, v) = (w_q, w_q J_q)
or per element (V_e, v_e): with J-bar = v/V,

    f_ai    += U'(J-bar) G_ai
    K_aibk  += U''(J-bar)/V G_ai G_bk + U'(J-bar) H_aibk
    G_ai     = dv/dx_ai           = sum_q w_q adj(F_q)_Ji dN_aJ          (adj F = J F^-1)
    H_aibk   = d2v/dx_ai dx_bk    = e_ik h_ab,   h_ab = sum_q w_q (dN_a0 dN_b1 - dN_a1 dN_b0)

with e the 2D permutation symbol (e_01 = 1 = -e_10). In 2D the current area
v = sum_q w_q det F_q is a quadratic form in the nodal positions (det dx/dxi is bilinear in x),
so H is constant. As w_q = w^ref_q det(dX/dxi) and dN/dX = dN/dxi (dX/dxi)^-1,

    h_ab = sum_q w^ref_q (dN_a/dxi dN_b/deta - dN_a/deta dN_b/dxi)(xi_q),

the same for every element of a type, curved T6 included (computed once). The degree-2
stiffness rule integrates v, G and h exactly, also for curved T6. For T3 (one point) the two
volumetric variants coincide.

Inverted elements: a quadrature point with J <= 0 makes every method that evaluates the material
raise ``InvertedElementError`` (attribute ``elements``: the offending element indices);
``inverted_elements(x)`` gives the same list without raising.
"""

from __future__ import annotations

from typing import NamedTuple

import numba
import numpy as np
import scipy.sparse as sp

from .elements import ElementType, QuadratureRule, element_type
from .topology import boundary_loop
from .material import (
    NeoHookean,
    isochoric_cauchy,
    isochoric_energy,
    isochoric_pk1,
    isochoric_pk1_tangent,
    volumetric_response,
    von_mises,
)

__all__ = [
    "FEBody",
    "ElementStresses",
    "ThetaSystem",
    "InvertedElementError",
    "VOLUMETRIC_FORMULATIONS",
]

VOLUMETRIC_FORMULATIONS = ("standard", "mean_dilatation")


class InvertedElementError(ValueError):
    """J <= 0 at a quadrature point; ``elements`` (k,) holds the element indices concerned."""

    def __init__(self, elements: np.ndarray) -> None:
        self.elements = elements
        super().__init__(
            f"{elements.size} element(s) with J <= 0 at a quadrature point: "
            f"{elements[:20].tolist()}{' ...' if elements.size > 20 else ''}"
        )


class ElementStresses(NamedTuple):
    """Per-element stresses, averages over the current element area.

    cauchy: (n_elem, 3, 3) plane-strain Cauchy stress (sigma_zz != 0; volumetric part from
    J-bar under mean dilatation); pressure: (n_elem,) -(s_xx + s_yy)/2, compression positive;
    von_mises: (n_elem,) 3D von Mises stress.
    """

    cauchy: np.ndarray
    pressure: np.ndarray
    von_mises: np.ndarray


class ThetaSystem(NamedTuple):
    """Newton system of one theta-scheme step (see ``FEBody.theta_system``).

    residual: (2n,); matrix: CSR (2n, 2n) = dR/dv+ = M + h^2 theta^2 K_t(x_theta);
    x_new: (n, 2) end-of-step positions; x_theta: (n, 2) the positions where the internal force
    is evaluated; f_int: (2n,) f_int(x_theta); k_data: (nnz,) K_t(x_theta) in the body's CSR
    pattern (to compare tangents between iterations without rebuilding matrices).
    """

    residual: np.ndarray
    matrix: sp.csr_matrix
    x_new: np.ndarray
    x_theta: np.ndarray
    f_int: np.ndarray
    k_data: np.ndarray


# ----------------------------------------------------------------------------- numba kernels


@numba.njit(cache=True, error_model="numpy")
def _gather(x: np.ndarray, nodes: np.ndarray, xe: np.ndarray) -> None:
    """xe (n_en, 2) <- x[nodes] for x (n_nodes, 2), nodes (n_en,)."""
    for a in range(nodes.size):
        xe[a, 0] = x[nodes[a], 0]
        xe[a, 1] = x[nodes[a], 1]


@numba.njit(cache=True, error_model="numpy")
def _deformation_gradient(xe: np.ndarray, dn: np.ndarray, F: np.ndarray) -> float:
    """F (2, 2) <- sum_a xe[a] (x) dn[a] for xe (n_en, 2), dn = dN/dX (n_en, 2); returns det F."""
    F[:] = 0.0
    for a in range(xe.shape[0]):
        for i in range(2):
            for j in range(2):
                F[i, j] += xe[a, i] * dn[a, j]
    return F[0, 0] * F[1, 1] - F[0, 1] * F[1, 0]


@numba.njit(cache=True, error_model="numpy")
def _jacobians(x: np.ndarray, cells: np.ndarray, dndX: np.ndarray) -> np.ndarray:
    """J = det F, (n_elem, n_q), at the points where dndX (n_elem, n_q, n_en, 2) is given."""
    n_elem, n_q, n_en, _ = dndX.shape
    J = np.empty((n_elem, n_q))
    xe = np.empty((n_en, 2))
    F = np.empty((2, 2))
    for e in range(n_elem):
        _gather(x, cells[e], xe)
        for q in range(n_q):
            J[e, q] = _deformation_gradient(xe, dndX[e, q], F)
    return J


@numba.njit(cache=True, error_model="numpy")
def _add_isochoric(
    F: np.ndarray, dn: np.ndarray, w: float, mu: float, with_tangent: bool,
    P: np.ndarray, A: np.ndarray, Ab: np.ndarray, fe: np.ndarray, ke: np.ndarray,
) -> None:
    """fe (n_en, 2) += w P dN; ke (n_en, 2, n_en, 2) += w dN A dN if with_tangent.

    P (2, 2), A (2, 2, 2, 2), Ab (2, 2, 2, n_en): work buffers.
    """
    n_en = dn.shape[0]
    if with_tangent:
        isochoric_pk1_tangent(F, mu, P, A)
        for i in range(2):  # Ab[i, J, k, b] = sum_L A[i, J, k, L] dN_b,L
            for j in range(2):
                for k in range(2):
                    for b in range(n_en):
                        Ab[i, j, k, b] = A[i, j, k, 0] * dn[b, 0] + A[i, j, k, 1] * dn[b, 1]
        for a in range(n_en):
            for i in range(2):
                for b in range(n_en):
                    for k in range(2):
                        ke[a, i, b, k] += w * (
                            dn[a, 0] * Ab[i, 0, k, b] + dn[a, 1] * Ab[i, 1, k, b]
                        )
    else:
        isochoric_pk1(F, mu, P)
    for a in range(n_en):
        for i in range(2):
            fe[a, i] += w * (P[i, 0] * dn[a, 0] + P[i, 1] * dn[a, 1])


@numba.njit(cache=True, error_model="numpy")
def _accumulate_volume(F: np.ndarray, dn: np.ndarray, w: float, G: np.ndarray) -> float:
    """G (n_en, 2) += dv/dx for v = w det F, dn = dN/dX (n_en, 2); returns v."""
    adj00, adj01, adj10, adj11 = F[1, 1], -F[0, 1], -F[1, 0], F[0, 0]
    for a in range(dn.shape[0]):
        G[a, 0] += w * (dn[a, 0] * adj00 + dn[a, 1] * adj10)
        G[a, 1] += w * (dn[a, 0] * adj01 + dn[a, 1] * adj11)
    return w * (F[0, 0] * F[1, 1] - F[0, 1] * F[1, 0])


@numba.njit(cache=True, error_model="numpy")
def _add_volumetric(
    v: float, V: float, G: np.ndarray, h: np.ndarray, kappa: float, with_tangent: bool,
    fe: np.ndarray, ke: np.ndarray,
) -> None:
    """fe, ke += force and tangent of V U(v / V), with G = dv/dx (n_en, 2) and h (n_en, n_en)
    the area Hessian factor (see module docstring)."""
    _, dU, d2U = volumetric_response(v / V, kappa)
    n_en = G.shape[0]
    for a in range(n_en):
        for i in range(2):
            fe[a, i] += dU * G[a, i]
    if with_tangent:
        c = d2U / V
        for a in range(n_en):
            for b in range(n_en):
                for i in range(2):
                    for k in range(2):
                        ke[a, i, b, k] += c * G[a, i] * G[b, k]
                ke[a, 0, b, 1] += dU * h[a, b]
                ke[a, 1, b, 0] -= dU * h[a, b]


@numba.njit(cache=True, error_model="numpy")
def _assemble_internal(
    x: np.ndarray, cells: np.ndarray, dndX: np.ndarray, wdV: np.ndarray, hessian: np.ndarray,
    mu: float, kappa: float, mean_dilatation: bool, with_tangent: bool, kmap: np.ndarray,
    f: np.ndarray, kdata: np.ndarray,
) -> bool:
    """f (2n,) <- f_int(x); kdata (nnz,) <- K_t(x) in the cached CSR pattern (if with_tangent).

    x (n, 2); cells (n_elem, n_en); dndX (n_elem, n_q, n_en, 2); wdV (n_elem, n_q);
    hessian: area Hessian factors h, (n_q, n_en, n_en) per point, or (1, n_en, n_en) summed
    over the element for mean dilatation;
    kmap (n_elem, 2 n_en, 2 n_en): position in kdata of each element matrix entry.
    Returns False (outputs incomplete) as soon as a quadrature point has J <= 0 (or NaN).
    """
    n_elem, n_q, n_en, _ = dndX.shape
    xe, fe, G = np.empty((n_en, 2)), np.empty((n_en, 2)), np.empty((n_en, 2))
    ke = np.empty((n_en, 2, n_en, 2))
    F, P, A = np.empty((2, 2)), np.empty((2, 2)), np.empty((2, 2, 2, 2))
    Ab = np.empty((2, 2, 2, n_en))
    f[:] = 0.0
    kdata[:] = 0.0
    for e in range(n_elem):
        _gather(x, cells[e], xe)
        fe[:] = 0.0
        ke[:] = 0.0
        G[:] = 0.0
        v = 0.0
        V = 0.0
        for q in range(n_q):
            if not _deformation_gradient(xe, dndX[e, q], F) > 0.0:  # J <= 0 or NaN
                return False
            w = wdV[e, q]
            _add_isochoric(F, dndX[e, q], w, mu, with_tangent, P, A, Ab, fe, ke)
            v += _accumulate_volume(F, dndX[e, q], w, G)
            V += w
            if not mean_dilatation:  # pointwise: apply, then restart the accumulation
                _add_volumetric(v, V, G, hessian[q], kappa, with_tangent, fe, ke)
                G[:] = 0.0
                v = 0.0
                V = 0.0
        if mean_dilatation:
            _add_volumetric(v, V, G, hessian[0], kappa, with_tangent, fe, ke)
        for a in range(n_en):
            for i in range(2):
                f[2 * cells[e, a] + i] += fe[a, i]
        if with_tangent:
            for a in range(n_en):
                for i in range(2):
                    for b in range(n_en):
                        for k in range(2):
                            kdata[kmap[e, 2 * a + i, 2 * b + k]] += ke[a, i, b, k]
    return True


@numba.njit(cache=True, error_model="numpy")
def _volumetric_geometric(
    x: np.ndarray, cells: np.ndarray, dndX: np.ndarray, wdV: np.ndarray, hessian: np.ndarray,
    kappa: float, mean_dilatation: bool, kmap: np.ndarray, kdata: np.ndarray,
) -> None:
    """kdata (nnz,) <- the volumetric geometric part of K_t, sum U'(J-bar) H (module
    docstring), with J-bar per quadrature point (standard) or per element (mean dilatation)."""
    n_elem, n_q, n_en, _ = dndX.shape
    xe = np.empty((n_en, 2))
    F = np.empty((2, 2))
    kdata[:] = 0.0
    for e in range(n_elem):
        _gather(x, cells[e], xe)
        v = 0.0
        V = 0.0
        for q in range(n_q):
            J = _deformation_gradient(xe, dndX[e, q], F)
            w = wdV[e, q]
            if mean_dilatation:
                v += w * J
                V += w
                continue
            _add_area_hessian(kdata, kmap[e], volumetric_response(J, kappa)[1], hessian[q])
        if mean_dilatation:
            _add_area_hessian(kdata, kmap[e], volumetric_response(v / V, kappa)[1], hessian[0])


@numba.njit(cache=True, inline="always")
def _add_area_hessian(kdata: np.ndarray, kmap_e: np.ndarray, dU: float, hessian_q: np.ndarray) -> None:
    """kdata += dU H for one element: H the (skew, x-y coupling) Hessian of the area, scattered
    through the element's map of (row dof, column dof) -> position in kdata."""
    n_en = hessian_q.shape[0]
    for a in range(n_en):
        for b in range(n_en):
            kdata[kmap_e[2 * a, 2 * b + 1]] += dU * hessian_q[a, b]
            kdata[kmap_e[2 * a + 1, 2 * b]] -= dU * hessian_q[a, b]


@numba.njit(cache=True, error_model="numpy")
def _strain_energy(
    x: np.ndarray, cells: np.ndarray, dndX: np.ndarray, wdV: np.ndarray, mu: float,
    kappa: float, mean_dilatation: bool,
) -> float:
    """Total strain energy E(x) (see module docstring); NaN if some J <= 0."""
    n_elem, n_q, n_en, _ = dndX.shape
    xe = np.empty((n_en, 2))
    F = np.empty((2, 2))
    energy = 0.0
    for e in range(n_elem):
        _gather(x, cells[e], xe)
        v = 0.0
        V = 0.0
        for q in range(n_q):
            J = _deformation_gradient(xe, dndX[e, q], F)
            w = wdV[e, q]
            energy += w * isochoric_energy(F, mu)
            if mean_dilatation:
                v += w * J
                V += w
            else:
                energy += w * volumetric_response(J, kappa)[0]
        if mean_dilatation:
            energy += V * volumetric_response(v / V, kappa)[0]
    return energy


@numba.njit(cache=True, error_model="numpy")
def _element_stresses(
    x: np.ndarray, cells: np.ndarray, dndX: np.ndarray, wdV: np.ndarray, mu: float,
    kappa: float, mean_dilatation: bool, cauchy: np.ndarray, pressure: np.ndarray,
    mises: np.ndarray,
) -> None:
    """Fill cauchy (n_elem, 3, 3), pressure (n_elem,), mises (n_elem,); NaN where J <= 0.

    sigma_e = (1/v_e) sum_q w_q J_q sigma_q, with the volumetric part U'(J_q) pointwise
    (standard) or U'(v_e / V_e) (mean dilatation).
    """
    n_elem, n_q, n_en, _ = dndX.shape
    xe = np.empty((n_en, 2))
    F, s_q = np.empty((2, 2)), np.empty((3, 3))
    for e in range(n_elem):
        _gather(x, cells[e], xe)
        s = cauchy[e]
        s[:] = 0.0
        v = 0.0
        V = 0.0
        vol = 0.0
        for q in range(n_q):
            J = _deformation_gradient(xe, dndX[e, q], F)
            wJ = wdV[e, q] * J
            isochoric_cauchy(F, mu, s_q)
            for i in range(3):
                for j in range(3):
                    s[i, j] += wJ * s_q[i, j]
            vol += wJ * volumetric_response(J, kappa)[1]
            v += wJ
            V += wdV[e, q]
        s /= v
        vol = volumetric_response(v / V, kappa)[1] if mean_dilatation else vol / v
        for i in range(3):
            s[i, i] += vol
        pressure[e] = -0.5 * (s[0, 0] + s[1, 1])
        mises[e] = von_mises(s)


# ------------------------------------------------------------------------ one-time set-up


def _reference_gradients(
    X: np.ndarray, cells: np.ndarray, element: ElementType, rule: QuadratureRule
) -> tuple[np.ndarray, np.ndarray]:
    """dN/dX (n_elem, n_q, n_en, 2) and w det(dX/dxi) (n_elem, n_q) at the points of ``rule``.

    Raises ValueError naming the elements whose reference Jacobian is <= 0 (clockwise node
    order or degenerate geometry).
    """
    dn_dxi = element.basis(rule.points)[1]
    jac = np.einsum("ean,qar->eqnr", X[cells], dn_dxi)
    det = jac[..., 0, 0] * jac[..., 1, 1] - jac[..., 0, 1] * jac[..., 1, 0]
    bad = np.flatnonzero((det <= 0.0).any(axis=1))
    if bad.size:
        raise ValueError(
            f"{bad.size} element(s) with a non-positive reference Jacobian (clockwise or "
            f"degenerate): {bad[:20].tolist()}"
        )
    dndX = np.einsum("qar,eqrn->eqan", dn_dxi, _inverse_2x2(jac, det))
    return np.ascontiguousarray(dndX), rule.weights * det


def _inverse_2x2(jac: np.ndarray, det: np.ndarray) -> np.ndarray:
    """The inverses (..., 2, 2) of the 2x2 matrices ``jac`` (..., 2, 2) with determinants ``det``
    (...,), by the adjugate. Not np.linalg.inv: LAPACK's last bits depend on the BLAS kernel the
    processor selects (compute.fixed_order), and these gradients enter every step."""
    inv = np.empty_like(jac)
    inv[..., 0, 0] = jac[..., 1, 1] / det
    inv[..., 0, 1] = -jac[..., 0, 1] / det
    inv[..., 1, 0] = -jac[..., 1, 0] / det
    inv[..., 1, 1] = jac[..., 0, 0] / det
    return inv


def _area_hessians(element: ElementType, mean_dilatation: bool) -> np.ndarray:
    """Area Hessian factors h_ab (module docstring) at the stiffness points, (n_q, n_en, n_en),
    or summed over them, (1, n_en, n_en), for mean dilatation."""
    rule = element.stiffness_rule
    dn = element.basis(rule.points)[1]
    h = np.einsum("q,qa,qb->qab", rule.weights, dn[..., 0], dn[..., 1])
    h = h - h.transpose(0, 2, 1)
    return h.sum(axis=0, keepdims=True) if mean_dilatation else h


def _sparsity(cells: np.ndarray, n_dof: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Canonical CSR pattern of the element dof pairs and the scatter map of the assembly.

    Returns indptr (n_dof + 1,) and indices (nnz,), read-only and of scipy's index dtype so that
    every matrix of the body shares them without a copy (in-place edits raise), and kmap
    (n_elem, 2 n_en, 2 n_en): the position in ``data`` of every element matrix entry.
    """
    dofs = (2 * cells[:, :, None] + np.arange(2)).reshape(cells.shape[0], -1)
    n_ed = dofs.shape[1]
    keys = np.repeat(dofs, n_ed, axis=1) * n_dof + np.tile(dofs, n_ed)
    unique, kmap = np.unique(keys, return_inverse=True)
    index_dtype = np.int32 if unique.size < 2**31 else np.int64
    indptr = np.concatenate([[0], np.cumsum(np.bincount(unique // n_dof, minlength=n_dof))])
    pattern = (indptr.astype(index_dtype), (unique % n_dof).astype(index_dtype))
    for array in pattern:
        array.flags.writeable = False
    return *pattern, kmap.reshape(cells.shape[0], n_ed, n_ed)


def check_connectivity(cells: np.ndarray, n_nodes: int, element: ElementType, volumetric: str) -> None:
    """ValueError unless cells (n_elem, n_en) are ``element``'s, reference nodes 0..n_nodes-1 and
    use every one of them, and ``volumetric`` is a known formulation."""
    if cells.ndim != 2 or cells.shape[1] != element.n_nodes:
        raise ValueError(f"cells must be (n_elem, {element.n_nodes}) for {element.name}, got {cells.shape}")
    if cells.min() < 0 or cells.max() >= n_nodes:
        raise ValueError(f"cells reference nodes outside 0..{n_nodes - 1}")
    unused = np.setdiff1d(np.arange(n_nodes), cells)
    if unused.size:
        raise ValueError(f"nodes not used by any element: {unused[:20].tolist()}")
    if volumetric not in VOLUMETRIC_FORMULATIONS:
        raise ValueError(f"volumetric must be one of {VOLUMETRIC_FORMULATIONS}, got {volumetric!r}")


# ----------------------------------------------------------------------------- the body


class FEBody:
    """A deformable body: reference mesh, material and the operators of its dynamics.

    X: (n_nodes, 2) reference positions; cells: (n_elem, 3 | 6) CCW connectivity (T6 in gmsh /
    meshio ``triangle6`` order); element: "T3" | "T6"; material: ``NeoHookean``;
    volumetric: "standard" | "mean_dilatation".

    Attributes: ``X`` (n, 2), ``cells``, ``n_nodes``, ``n_dof`` = 2n; ``mass`` CSR (2n, 2n)
    consistent mass matrix (explicit zeros in the x-y couplings: the pattern, whose read-only
    index arrays all the body's matrices share, is that of K_t); ``reference_areas``
    (n_elem,); ``boundary`` (n_b,) CCW boundary loop.
    """

    def __init__(
        self, X: np.ndarray, cells: np.ndarray, element: str, material: NeoHookean,
        volumetric: str,
    ) -> None:
        self.element = element_type(element)
        X = np.ascontiguousarray(X, dtype=np.float64)
        cells = np.ascontiguousarray(cells, dtype=np.int64)
        if X.ndim != 2 or X.shape[1] != 2 or not np.isfinite(X).all():
            raise ValueError(f"X must be a finite (n_nodes, 2) array, got shape {X.shape}")
        check_connectivity(cells, X.shape[0], self.element, volumetric)
        self.X, self.cells, self.material, self.volumetric = X, cells, material, volumetric
        self.n_nodes, self.n_dof = X.shape[0], 2 * X.shape[0]
        self._mean_dilatation = volumetric == "mean_dilatation"

        stiffness_rule, mass_rule = self.element.stiffness_rule, self.element.mass_rule
        self._dndX, self._wdV = _reference_gradients(X, cells, self.element, stiffness_rule)
        self._dndX_m, self._wdV_m = _reference_gradients(X, cells, self.element, mass_rule)
        self._N_m = self.element.basis(mass_rule.points)[0]
        self._area_hessian = _area_hessians(self.element, self._mean_dilatation)
        self._indptr, self._indices, self._kmap = _sparsity(cells, self.n_dof)
        self.reference_areas = self._wdV.sum(axis=1)
        self.boundary = boundary_loop(cells, self.element)

        m_e = material.density * np.einsum("eq,qa,qb->eab", self._wdV_m, self._N_m, self._N_m)
        mass = np.zeros(self._indices.size)
        for i in range(2):
            np.add.at(mass, self._kmap[:, i::2, i::2], m_e)
        self.mass = self._csr(mass)

    def _csr(self, data: np.ndarray) -> sp.csr_matrix:
        """CSR matrix (2n, 2n) with the body's sparsity pattern and values data (nnz,)."""
        return sp.csr_matrix((data, self._indices, self._indptr), shape=(self.n_dof, self.n_dof))

    def _positions(self, x: np.ndarray) -> np.ndarray:
        x = np.ascontiguousarray(x, dtype=np.float64)
        if x.shape != (self.n_nodes, 2):
            raise ValueError(f"positions must have shape ({self.n_nodes}, 2), got {x.shape}")
        return x

    def _assemble(self, x: np.ndarray, with_tangent: bool) -> tuple[np.ndarray, np.ndarray]:
        x = self._positions(x)
        f = np.empty(self.n_dof)
        kdata = np.empty(self._indices.size if with_tangent else 0)
        mat = self.material
        if not _assemble_internal(
            x, self.cells, self._dndX, self._wdV, self._area_hessian, mat.mu, mat.kappa,
            self._mean_dilatation, with_tangent, self._kmap, f, kdata,
        ):
            raise InvertedElementError(self.inverted_elements(x))
        return f, kdata

    def internal_force(self, x: np.ndarray) -> np.ndarray:
        """f_int(x) = dE/dx, (2n,), for current positions x (n, 2)."""
        return self._assemble(x, False)[0]

    def internal_force_and_tangent(self, x: np.ndarray) -> tuple[np.ndarray, sp.csr_matrix]:
        """f_int(x) (2n,) and the consistent tangent K_t = d f_int / dx, CSR (2n, 2n)."""
        f, kdata = self._assemble(x, True)
        return f, self._csr(kdata)

    def strain_energy(self, x: np.ndarray) -> float:
        """Total strain energy E(x) per unit thickness."""
        x = self._positions(x)
        mat = self.material
        energy = _strain_energy(
            x, self.cells, self._dndX, self._wdV, mat.mu, mat.kappa, self._mean_dilatation
        )
        if not np.isfinite(energy):
            raise InvertedElementError(self.inverted_elements(x))
        return energy

    def element_stresses(self, x: np.ndarray) -> ElementStresses:
        """Per-element Cauchy stress (n_elem, 3, 3), pressure and von Mises (n_elem,) at x."""
        x = self._positions(x)
        bad = self.inverted_elements(x)
        if bad.size:
            raise InvertedElementError(bad)
        n_elem, mat = self.cells.shape[0], self.material
        out = ElementStresses(np.empty((n_elem, 3, 3)), np.empty(n_elem), np.empty(n_elem))
        _element_stresses(
            x, self.cells, self._dndX, self._wdV, mat.mu, mat.kappa, self._mean_dilatation, *out
        )
        return out

    def area(self, x: np.ndarray) -> float:
        """Current area of the body (exact, curved T6 included)."""
        return float(np.sum(self._wdV * _jacobians(self._positions(x), self.cells, self._dndX)))

    def centroid(self, x: np.ndarray) -> np.ndarray:
        """Current centroid (2,) = (1/a) integral of x over the current body (exact)."""
        x = self._positions(x)
        da = self._wdV_m * _jacobians(x, self.cells, self._dndX_m)  # (n_elem, n_q)
        moment = np.einsum("eq,qa,eai->i", da, self._N_m, x[self.cells])
        return moment / da.sum()

    def volumetric_geometric_data(self, x: np.ndarray) -> np.ndarray:
        """Values (nnz,) of the volumetric geometric stiffness, the part sum U'(J-bar) H of
        K_t (module docstring) in the body's CSR pattern. U' = -pressure, and H (the Hessian of
        the current area of an element or a quadrature point's share) is indefinite: under
        compression this term gives K_t negative directions along a pressed boundary (the
        boundary-node 'wrinkling' modes) that only the contacts hold."""
        x = self._positions(x)
        kdata = np.empty(self._indices.size)
        _volumetric_geometric(x, self.cells, self._dndX, self._wdV, self._area_hessian, self.material.kappa,
                              self._mean_dilatation, self._kmap, kdata)
        return kdata

    def jacobians(self, x: np.ndarray) -> np.ndarray:
        """J = det F (n_elem, n_q) at the stiffness quadrature points for positions x (n, 2)."""
        return _jacobians(self._positions(x), self.cells, self._dndX)

    def inverted_elements(self, x: np.ndarray) -> np.ndarray:
        """Indices (k,) of the elements with J <= 0 (or NaN) at some stiffness quadrature point."""
        J = _jacobians(self._positions(x), self.cells, self._dndX)
        return np.flatnonzero(~(J > 0.0).all(axis=1))

    def theta_positions(
        self, x_n: np.ndarray, v_n: np.ndarray, v_new: np.ndarray, h: float, theta: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """(x_theta, x_new), both (n, 2), of a theta step from x_n (n, 2) with velocities v_n,
        v_new (2n,): x_new = x_n + h ((1 - theta) v_n + theta v_new), x_theta = x_n + theta
        (x_new - x_n)."""
        dx = h * ((1.0 - theta) * np.asarray(v_n) + theta * np.asarray(v_new)).reshape(-1, 2)
        return np.asarray(x_n) + theta * dx, np.asarray(x_n) + dx

    def effective_matrix_data(self, k_data: np.ndarray, h: float, theta: float) -> np.ndarray:
        """Values (nnz,) of M_hat = M + h^2 theta^2 K_t in the body's CSR pattern."""
        return self.mass.data + (h * theta) ** 2 * k_data

    def csr(self, data: np.ndarray) -> sp.csr_matrix:
        """CSR matrix (2n, 2n) in the body's sparsity pattern with values ``data`` (nnz,)."""
        return self._csr(data)

    def theta_system(
        self, v_new: np.ndarray, x_n: np.ndarray, v_n: np.ndarray, f_ext_n: np.ndarray,
        f_ext_new: np.ndarray, h: float, theta: float,
    ) -> ThetaSystem:
        r"""Newton residual and matrix of one theta-scheme step without contact.

        Unknown: end-of-step velocity v_new (2n,). Given x_n (n, 2), v_n, f_ext_n, f_ext_new
        (all (2n,)), time step h and theta in [1/2, 1]:

            x_new   = x_n + h ((1 - theta) v_n + theta v_new)
            x_theta = x_n + theta (x_new - x_n) = x_n + theta h ((1 - theta) v_n + theta v_new)
            R(v_new) = M (v_new - v_n) + h f_int(x_theta) - h [(1 - theta) f_ext_n + theta f_ext_new]
            dR/dv_new = M_hat = M + h^2 theta^2 K_t(x_theta)

        Signs: the balance is M dv/dt + f_int(x) = f_ext (+ contact forces), f_int = dE/dx; the
        contact impulse r (2n,) of a Moreau-Jean step enters as R(v_new) = r. A Newton
        iteration is v_new <- v_new - M_hat^-1 R.

        Momenta. Linear momentum is conserved exactly (f_int sums to zero over the nodes). At
        theta = 1/2, x_theta = (x_n + x_new)/2 is the midpoint and the scheme is the implicit
        midpoint rule: angular momentum L = sum_a x_a x (M v)_a is conserved exactly too. With
        vbar = (v_n + v_new)/2, x_new = x_theta + h vbar/2, x_n = x_theta - h vbar/2 and
        M (v_new - v_n) = -h f_int(x_theta):
            L_new - L_n = -h sum_a x_theta,a x f_int,a + h sum_ab m_ab vbar_a x vbar_b = 0,
        the first sum because f_int has no torque at any configuration, the second because the
        consistent mass blocks m_ab I are symmetric in (a, b). At theta = 1 this is backward
        Euler, x_theta = x_new, with numerical dissipation of the high frequencies (the
        quasi-static setting). The internal force is never evaluated at x_n, so a step needs no f_int_n.
        """
        x_theta, x_new = self.theta_positions(x_n, v_n, v_new, h, theta)
        f, k_data = self._assemble(x_theta, True)
        residual = (
            self.mass @ (np.asarray(v_new) - v_n)
            + h * f
            - h * ((1.0 - theta) * np.asarray(f_ext_n) + theta * np.asarray(f_ext_new))
        )
        matrix = self._csr(self.effective_matrix_data(k_data, h, theta))
        return ThetaSystem(residual, matrix, x_new, x_theta, f, k_data)
