r"""Finite-element operators of a whole group of deformable bodies at once (numba, parallel).

A scene holds hundreds of deformable disks made from one reference mesh: the same connectivity
``cells``, element type, material and volumetric formulation, each body with its own reference
node positions (a scaled and translated copy). Calling ``FEBody`` once per body spends most of
the time in Python; ``BodyBatch`` stores the per-body reference data of the whole group in
stacked arrays (leading axis: body) and evaluates every operator for all bodies in one numba
call, ``prange`` over bodies, each body handled by the per-body kernels of
``compute.fem.body`` (so the element formulas exist once, and the results are those of
``FEBody``). Conventions (dof order, CSR pattern, energy, f_int, K_t, volumetric formulations)
are those of ``compute.fem.body``; every body matrix has the same CSR pattern, so matrices of
the group are (B, nnz) value arrays on one shared (indptr, indices).

Inverted elements (J <= 0 or NaN at a stiffness point) never raise here: the assembly returns
a per-body ``ok`` flag, and the diagnostics (energies, stresses, volumetric geometric data) are
NaN where the material cannot be evaluated (check with ``jacobians``).

Memory. Stored per body: X (n_nodes, 2), dN/dX at the stiffness points (n_elem, n_q, n_en, 2),
their weights (n_elem, n_q), reference_areas (n_elem,) and mass_data (nnz,), all float64; the
connectivity, the CSR pattern and its scatter map kmap (n_elem, 2 n_en, 2 n_en) are shared.
For the 92-element gmsh disk:

    T3 (57 nodes,  nnz 1412): 912 + 4416 + 736 + 736 + 11296  = 18,096 bytes  (~17.7 KiB) per body
    T6 (205 nodes, nnz 8788): 3280 + 26496 + 2208 + 736 + 70304 = 103,024 bytes (~101 KiB) per body

(shared: kmap 26 KB (T3) / 106 KB (T6), indices 4 nnz bytes). A caller's work arrays f (B, 2n)
and kdata (B, nnz) add 12.2 KB (T3) / 73.6 KB (T6) per body. (An ``FEBody`` keeps its own kmap,
pattern, area Hessian and mass-rule gradients too: about 80 KB (T3) / 379 KB (T6).)
"""

from __future__ import annotations

import numba
import numpy as np

from .body import (
    ElementStresses,
    _area_hessians,
    _assemble_internal,
    _element_stresses,
    _inverse_2x2,
    _jacobians,
    _sparsity,
    _strain_energy,
    _volumetric_geometric,
    check_connectivity,
)
from .elements import ElementType, QuadratureRule, element_type
from .topology import boundary_loop
from .material import NeoHookean

__all__ = ["BodyBatch"]


# ----------------------------------------------------------------------------- numba kernels
# Each kernel runs the per-body kernel of body.py on body b = 0..B-1 in a prange loop; per-body
# arrays are indexed on their leading axis (C-contiguous views, no copies).


@numba.njit(cache=True, parallel=True, error_model="numpy")
def _batch_internal(
    x: np.ndarray, active: np.ndarray, cells: np.ndarray, dndX: np.ndarray, wdV: np.ndarray,
    hessian: np.ndarray, mu: float, kappa: float, mean_dilatation: bool, with_tangent: bool,
    kmap: np.ndarray, f: np.ndarray, kdata: np.ndarray, ok: np.ndarray,
) -> None:
    """For active bodies: f[b] (2n,) <- f_int(x[b]), kdata[b] (nnz,) <- K_t(x[b]) (if
    with_tangent; kdata may be (B, 0) otherwise), ok[b] <- no inverted element. Inactive:
    ok[b] <- True, f and kdata untouched. x (B, n, 2), dndX (B, n_elem, n_q, n_en, 2),
    wdV (B, n_elem, n_q), active and ok (B,)."""
    for b in numba.prange(x.shape[0]):
        if active[b]:
            ok[b] = _assemble_internal(
                x[b], cells, dndX[b], wdV[b], hessian, mu, kappa, mean_dilatation, with_tangent,
                kmap, f[b], kdata[b],
            )
        else:
            ok[b] = True


@numba.njit(cache=True, parallel=True, error_model="numpy")
def _batch_volumetric_geometric(
    x: np.ndarray, active: np.ndarray, cells: np.ndarray, dndX: np.ndarray, wdV: np.ndarray,
    hessian: np.ndarray, kappa: float, mean_dilatation: bool, kmap: np.ndarray, out: np.ndarray,
) -> None:
    """out[b] (nnz,) <- volumetric geometric stiffness of body b, for the active bodies."""
    for b in numba.prange(x.shape[0]):
        if active[b]:
            _volumetric_geometric(
                x[b], cells, dndX[b], wdV[b], hessian, kappa, mean_dilatation, kmap, out[b]
            )


@numba.njit(cache=True, parallel=True, error_model="numpy")
def _batch_jacobians(x: np.ndarray, cells: np.ndarray, dndX: np.ndarray, J: np.ndarray) -> None:
    """J (B, n_elem, n_q) <- det F of every body at the points where dndX is given."""
    for b in numba.prange(x.shape[0]):
        J[b] = _jacobians(x[b], cells, dndX[b])


@numba.njit(cache=True, parallel=True, error_model="numpy")
def _batch_strain_energy(
    x: np.ndarray, cells: np.ndarray, dndX: np.ndarray, wdV: np.ndarray, mu: float,
    kappa: float, mean_dilatation: bool, energy: np.ndarray,
) -> None:
    """energy (B,) <- strain energy of every body (NaN where some J <= 0)."""
    for b in numba.prange(x.shape[0]):
        energy[b] = _strain_energy(x[b], cells, dndX[b], wdV[b], mu, kappa, mean_dilatation)


@numba.njit(cache=True, parallel=True, error_model="numpy")
def _batch_element_stresses(
    x: np.ndarray, cells: np.ndarray, dndX: np.ndarray, wdV: np.ndarray, mu: float,
    kappa: float, mean_dilatation: bool, cauchy: np.ndarray, pressure: np.ndarray,
    mises: np.ndarray,
) -> None:
    """cauchy (B, n_elem, 3, 3), pressure and mises (B, n_elem) of every body."""
    for b in numba.prange(x.shape[0]):
        _element_stresses(
            x[b], cells, dndX[b], wdV[b], mu, kappa, mean_dilatation, cauchy[b], pressure[b],
            mises[b],
        )


@numba.njit(cache=True, parallel=True, error_model="numpy")
def _batch_csr_matvec(
    indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, v: np.ndarray, out: np.ndarray
) -> None:
    """out[b] <- A_b v[b] for CSR matrices A_b sharing (indptr, indices), values data (B, nnz);
    v, out (B, n_rows)."""
    n_rows = indptr.size - 1
    for b in numba.prange(v.shape[0]):
        for i in range(n_rows):
            s = 0.0
            for k in range(indptr[i], indptr[i + 1]):
                s += data[b, k] * v[b, indices[k]]
            out[b, i] = s


@numba.njit(cache=True, parallel=True, error_model="numpy")
def _batch_jacobian_ratio_range(x, cells, dndX, j_ref, out):
    """out[b] <- (min, max) over elements and points of det F(x[b]) / j_ref[b] (no temporaries)."""
    n_elem, n_q, n_en = dndX.shape[1], dndX.shape[2], dndX.shape[3]
    for b in numba.prange(x.shape[0]):
        lo, hi = np.inf, -np.inf
        for e in range(n_elem):
            for q in range(n_q):
                f00 = f01 = f10 = f11 = 0.0
                for a in range(n_en):
                    xa, ya = x[b, cells[e, a], 0], x[b, cells[e, a], 1]
                    gx, gy = dndX[b, e, q, a, 0], dndX[b, e, q, a, 1]
                    f00 += xa * gx
                    f01 += xa * gy
                    f10 += ya * gx
                    f11 += ya * gy
                r = (f00 * f11 - f01 * f10) / j_ref[b, e, q]
                if not (r >= lo):  # also catches NaN
                    lo = r
                if not (r <= hi):
                    hi = r
        out[b, 0], out[b, 1] = lo, hi


@numba.njit(cache=True, parallel=True)
def _batch_axpy(m: np.ndarray, c: float, k: np.ndarray, active: np.ndarray) -> None:
    """k[b] <- m[b] + c k[b] for the active rows b of (B, nnz) arrays."""
    for b in numba.prange(k.shape[0]):
        if active[b]:
            for i in range(k.shape[1]):
                k[b, i] = m[b, i] + c * k[b, i]


# ------------------------------------------------------------------------ one-time set-up


def _batch_reference_gradients(
    X: np.ndarray, cells: np.ndarray, element: ElementType, rule: QuadratureRule
) -> tuple[np.ndarray, np.ndarray]:
    """dN/dX (B, n_elem, n_q, n_en, 2) and w det(dX/dxi) (B, n_elem, n_q) of every body at the
    points of ``rule`` (body.py's ``_reference_gradients`` with a leading body axis).

    Raises ValueError naming the first body (and its elements) with a reference Jacobian <= 0.
    """
    dn_dxi = element.basis(rule.points)[1]  # (n_q, n_en, 2)
    jac = np.einsum("bean,qar->beqnr", X[:, cells], dn_dxi)  # (B, n_elem, n_q, 2, 2)
    det = jac[..., 0, 0] * jac[..., 1, 1] - jac[..., 0, 1] * jac[..., 1, 0]
    bad = (det <= 0.0).any(axis=2)  # (B, n_elem)
    if bad.any():
        bodies = np.flatnonzero(bad.any(axis=1))
        elements = np.flatnonzero(bad[bodies[0]])
        raise ValueError(
            f"body {bodies[0]}: {elements.size} element(s) with a non-positive reference "
            f"Jacobian (clockwise or degenerate): {elements[:20].tolist()}"
            + (f" (bodies concerned: {bodies[:20].tolist()})" if bodies.size > 1 else "")
        )
    dndX = np.einsum("qar,beqrn->beqan", dn_dxi, _inverse_2x2(jac, det))
    return np.ascontiguousarray(dndX), rule.weights * det


# ----------------------------------------------------------------------------- the batch


class BodyBatch:
    """B deformable bodies sharing connectivity ``cells`` (n_elem, n_en), element type, material
    and volumetric formulation; reference positions X (B, n_nodes, 2) (one per body).

    Attributes: B, n_nodes, n_dof (= 2 n_nodes), cells, element (ElementType), material
    (NeoHookean), volumetric, indptr (n_dof + 1,), indices (nnz,) the shared CSR pattern of
    every body matrix (the pattern of FEBody: every dof pair of every element; read-only),
    kmap (n_elem, 2 n_en, 2 n_en) as in body.py, mass_data (B, nnz) consistent mass matrices in
    that pattern (the material's times ``mass_scale``, :meth:`scale_mass`), reference_areas (B, n_elem), boundary (n_b,) the CCW boundary loop (shared),
    X (B, n_nodes, 2).
    Raises ValueError (naming the body index) for an invalid mesh, as FEBody does.

    Positions x are (B, n_nodes, 2) arrays, nodal vectors (B, 2 n_nodes) in FEBody's dof order.
    Output arrays passed in (f, kdata, out) must be C-contiguous float64 of the stated shape.
    """

    def __init__(
        self, X: np.ndarray, cells: np.ndarray, element: str, material: NeoHookean,
        volumetric: str,
    ) -> None:
        self.element = element_type(element)
        X = np.array(X, dtype=np.float64, order="C")  # own copy
        cells = np.array(cells, dtype=np.int64, order="C")  # own, writeable copy
        if X.ndim != 3 or X.shape[2] != 2 or X.shape[0] < 1:
            raise ValueError(f"X must be a (B >= 1, n_nodes, 2) array, got shape {X.shape}")
        not_finite = np.flatnonzero(~np.isfinite(X).all(axis=(1, 2)))
        if not_finite.size:
            raise ValueError(f"body {not_finite[0]}: X is not finite (bodies concerned: "
                             f"{not_finite[:20].tolist()})")
        check_connectivity(cells, X.shape[1], self.element, volumetric)
        self.X, self.cells, self.material, self.volumetric = X, cells, material, volumetric
        self.B, self.n_nodes = X.shape[0], X.shape[1]
        self.n_dof = 2 * self.n_nodes
        self._mean_dilatation = volumetric == "mean_dilatation"

        stiffness_rule, mass_rule = self.element.stiffness_rule, self.element.mass_rule
        self._dndX, self._wdV = _batch_reference_gradients(X, cells, self.element, stiffness_rule)
        self._area_hessian = _area_hessians(self.element, self._mean_dilatation)
        self.indptr, self.indices, self.kmap = _sparsity(cells, self.n_dof)
        self.reference_areas = self._wdV.sum(axis=2)
        self.boundary = boundary_loop(cells, self.element)

        # centroids are integrated with the mass rule directly on the current configuration:
        # da = w_q det(dx/dxi), so only the (shared) shape functions are kept
        self._N_m, self._dn_dxi_m = self.element.basis(mass_rule.points)
        self._w_m = mass_rule.weights

        # consistent mass matrices (B, nnz), as FEBody (the mass-rule gradients are temporary)
        _, wdV_m = _batch_reference_gradients(X, cells, self.element, mass_rule)
        m_e = material.density * np.einsum("zeq,qa,qc->zeac", wdV_m, self._N_m, self._N_m)
        mass = np.zeros((self.indices.size, self.B))  # body axis last for np.add.at
        for i in range(2):
            np.add.at(mass, self.kmap[:, i::2, i::2], m_e.transpose(1, 2, 3, 0))
        self.mass_data = np.ascontiguousarray(mass.T)
        self.mass_scale, self._material_mass = 1.0, None

    # ---------------------------------------------------------------------- argument checks

    def _positions(self, x: np.ndarray) -> np.ndarray:
        x = np.ascontiguousarray(x, dtype=np.float64)
        if x.shape != (self.B, self.n_nodes, 2):
            raise ValueError(
                f"positions must have shape ({self.B}, {self.n_nodes}, 2), got {x.shape}"
            )
        return x

    def _active(self, active: np.ndarray) -> np.ndarray:
        active = np.ascontiguousarray(active, dtype=np.bool_)
        if active.shape != (self.B,):
            raise ValueError(f"active must have shape ({self.B},), got {active.shape}")
        return active

    @staticmethod
    def _output(array: np.ndarray, shape: tuple[int, ...], name: str) -> np.ndarray:
        if not (
            isinstance(array, np.ndarray) and array.dtype == np.float64
            and array.shape == shape and array.flags.c_contiguous and array.flags.writeable
        ):
            raise ValueError(
                f"{name} must be a writeable C-contiguous float64 array of shape {shape}, got "
                f"{getattr(array, 'dtype', type(array))} {getattr(array, 'shape', '')}"
            )
        return array

    # ------------------------------------------------------------------------- assembly

    def _assemble(self, x, active, f, kdata, with_tangent: bool) -> np.ndarray:
        x, active = self._positions(x), self._active(active)
        self._output(f, (self.B, self.n_dof), "f")
        if with_tangent:
            self._output(kdata, (self.B, self.indices.size), "kdata")
        ok = np.empty(self.B, dtype=np.bool_)
        mat = self.material
        _batch_internal(
            x, active, self.cells, self._dndX, self._wdV, self._area_hessian, mat.mu,
            mat.kappa, self._mean_dilatation, with_tangent, self.kmap, f, kdata, ok,
        )
        return ok

    def internal_force_and_tangent(
        self, x: np.ndarray, active: np.ndarray, f: np.ndarray, kdata: np.ndarray
    ) -> np.ndarray:
        """For every body b with active[b] (B,) bool: f[b] (2n,) <- f_int(x[b]), kdata[b] (nnz,)
        <- K_t(x[b]) in the shared pattern; x (B, n_nodes, 2), f (B, 2n), kdata (B, nnz).
        Returns ok (B,) bool: False where some element is inverted (J <= 0 or NaN; outputs of
        that body incomplete). Inactive bodies: untouched, ok True."""
        return self._assemble(x, active, f, kdata, True)

    def internal_force(self, x: np.ndarray, active: np.ndarray, f: np.ndarray) -> np.ndarray:
        """f[b] (2n,) <- f_int(x[b]) for the active bodies; x (B, n_nodes, 2), f (B, 2n).
        Returns ok (B,) bool as ``internal_force_and_tangent``."""
        return self._assemble(x, active, f, np.empty((self.B, 0)), False)

    def volumetric_geometric(self, x: np.ndarray, active: np.ndarray, out: np.ndarray) -> None:
        """out[b] (nnz,) <- FEBody.volumetric_geometric_data(x[b]) for the active bodies (the
        part sum U'(J-bar) H of K_t); x (B, n_nodes, 2), out (B, nnz). NaN where some J <= 0;
        inactive bodies untouched."""
        x, active = self._positions(x), self._active(active)
        self._output(out, (self.B, self.indices.size), "out")
        _batch_volumetric_geometric(
            x, active, self.cells, self._dndX, self._wdV, self._area_hessian,
            self.material.kappa, self._mean_dilatation, self.kmap, out,
        )

    def effective_matrix(self, kdata: np.ndarray, c: float, active: np.ndarray) -> None:
        """kdata[b] <- M_b + c kdata[b] (the θ-scheme's M̂ = M + h²θ² K_t for c = h²θ²), in
        place, for the active bodies; kdata (B, nnz)."""
        self._output(kdata, (self.B, self.indices.size), "kdata")
        _batch_axpy(self.mass_data, c, kdata, self._active(active))

    def scale_mass(self, factor: float) -> None:
        """Make the mass matrices ``factor`` times the material's (mass scaling:
        compute.bodies.soft.mass_scale), always from the material's, so that the same factor
        gives the same matrices bit for bit whatever was set before."""
        if factor == self.mass_scale:
            return
        if self._material_mass is None:
            self._material_mass = self.mass_data.copy()
        np.multiply(self._material_mass, factor, out=self.mass_data)
        self.mass_scale = float(factor)

    def mass_times(self, v: np.ndarray, out: np.ndarray | None = None, material: bool = False) -> np.ndarray:
        """M_b v_b for v (B, 2n) -> (B, 2n) (batched CSR mat-vec on the shared pattern), written
        to ``out`` (B, 2n) if given (must not be v); with ``material``, M_b the material's mass
        whatever the scaling (weights)."""
        v = np.ascontiguousarray(v, dtype=np.float64)
        if v.shape != (self.B, self.n_dof):
            raise ValueError(f"v must have shape ({self.B}, {self.n_dof}), got {v.shape}")
        if out is None:
            out = np.empty((self.B, self.n_dof))
        else:
            self._output(out, (self.B, self.n_dof), "out")
            if np.shares_memory(out, v):
                raise ValueError("mass_times: out must not overlap v")
        mass = self._material_mass if material and self._material_mass is not None else self.mass_data
        _batch_csr_matvec(self.indptr, self.indices, mass, v, out)
        return out

    # ---------------------------------------------------------------------- diagnostics

    def jacobians(self, x: np.ndarray) -> np.ndarray:
        """J = det F (B, n_elem, n_q) at the stiffness quadrature points; x (B, n_nodes, 2)."""
        x = self._positions(x)
        J = np.empty(self._wdV.shape)
        _batch_jacobians(x, self.cells, self._dndX, J)
        return J

    def jacobian_ratio_range(self, x: np.ndarray, j_ref: np.ndarray) -> np.ndarray:
        """Smallest and largest J(x) / j_ref over the stiffness points of every body, (B, 2);
        x (B, n_nodes, 2), j_ref (B, n_elem, n_q) (e.g. ``jacobians`` of the step's start).
        NaN where some J is NaN."""
        x = self._positions(x)
        if j_ref.shape != self._wdV.shape:
            raise ValueError(f"j_ref must have shape {self._wdV.shape}, got {j_ref.shape}")
        out = np.empty((self.B, 2))
        _batch_jacobian_ratio_range(x, self.cells, self._dndX, np.ascontiguousarray(j_ref), out)
        return out

    def areas(self, x: np.ndarray) -> np.ndarray:
        """Current areas (B,) of the bodies (exact, curved T6 included, as FEBody.area)."""
        return np.einsum("beq,beq->b", self._wdV, self.jacobians(x))

    def centroids(self, x: np.ndarray) -> np.ndarray:
        """Current centroids (B, 2) = (1/a) integral of x over each current body (exact, as
        FEBody.centroid: mass rule, da = w_q det(dx/dxi))."""
        xe = self._positions(x)[:, self.cells]  # (B, n_elem, n_en, 2)
        jac = np.einsum("bean,qar->beqnr", xe, self._dn_dxi_m)
        da = self._w_m * (jac[..., 0, 0] * jac[..., 1, 1] - jac[..., 0, 1] * jac[..., 1, 0])
        moment = np.einsum("beq,qa,beai->bi", da, self._N_m, xe)
        return moment / da.sum(axis=(1, 2))[:, None]

    def element_stresses(self, x: np.ndarray) -> ElementStresses:
        """Per-element stresses of every body (FEBody.element_stresses with a leading body
        axis): cauchy (B, n_elem, 3, 3), pressure (B, n_elem), von_mises (B, n_elem); NaN for
        the elements with J <= 0 (no exception)."""
        x = self._positions(x)
        n_elem, mat = self.cells.shape[0], self.material
        out = ElementStresses(
            np.empty((self.B, n_elem, 3, 3)), np.empty((self.B, n_elem)),
            np.empty((self.B, n_elem)),
        )
        _batch_element_stresses(
            x, self.cells, self._dndX, self._wdV, mat.mu, mat.kappa, self._mean_dilatation, *out
        )
        return out

    def strain_energy(self, x: np.ndarray) -> np.ndarray:
        """Strain energies (B,) per unit thickness; NaN for a body with some J <= 0."""
        x = self._positions(x)
        energy = np.empty(self.B)
        mat = self.material
        _batch_strain_energy(
            x, self.cells, self._dndX, self._wdV, mat.mu, mat.kappa, self._mean_dilatation,
            energy,
        )
        return energy

    def kinetic_energy(self, v: np.ndarray) -> float:
        """Total kinetic energy sum_b 1/2 v_b . M_b v_b of the group, v (B, 2n)."""
        v = np.ascontiguousarray(v, dtype=np.float64)
        return float(0.5 * np.einsum("bi,bi->", v, self.mass_times(v)))
