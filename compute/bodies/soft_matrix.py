r"""The Newton matrices M̂_b = M_b + h²θ² K_t,b of a group of soft bodies, factorised together.

One symbolic LDLᵀ for the group's shared pattern (:class:`compute.fem.ldl.SymbolicLDL`), numeric
factorisations, solves and compliance blocks for all bodies at once. Per body:

- Reuse: a factorisation is kept while M̂ barely changes (largest entry change below
  ``change_limit`` of the largest entry, same (h, θ)) unless the caller forces it (a kept
  factorisation that contracted the Newton correction too slowly).
- Positive definiteness: the Delassus operator needs a positive definite M̂, which a pressed
  body loses at large h: its volumetric geometric stiffness U'(J) ∂²(area)/∂x² is indefinite
  along a pressed boundary, and the moment of the compressive loads makes the rigid rotation
  unstable; the contacts hold both. The number of negative pivots of LDLᵀ is the inertia of M̂
  (Sylvester); when it is not zero the body falls back to level 1, M̂ without the volumetric
  geometric stiffness G, then to levels 2.., M̂ - G + s h²θ² μ/(ρR²) M (s in ``SHIFTS``: a
  mass-proportional stiffness), the first positive definite one being kept. A body starts at the
  level its last factorisation ended with (same h, θ).
- Compliance blocks C_b = E_bᵀ M̂_b⁻¹ E_b on the dofs contacts touch are recomputed only for bodies
  whose factorisation or contact dofs changed.
- A held direction (:meth:`NewtonMatrices.hold`): with c_b (n,) held, each body's velocities
  are restricted to c_bᵀ v = 0 by a multiplier λ_b, and the matrices stand for the compliance of
  the bordered system [M̂ −c; cᵀ 0] instead of M̂⁻¹ (a rank-one update, z = M̂⁻¹ c, s = cᵀ z):

      G = M̂⁻¹ − z zᵀ / s,      Newton step: v − G R(v) − z (cᵀ v) / s   (whose cᵀ v is 0)

  G = Z (Zᵀ M̂ Z)⁻¹ Zᵀ for a basis Z of the velocities with cᵀ v = 0, so the Delassus operator
  HᵀGH is positive semi-definite exactly when Zᵀ M̂ Z is positive definite, which by the inertia
  of the bordered matrix (Haynsworth) is: no negative pivot, or one negative pivot and s < 0.
  A factorisation is accepted on that test: a pressed body whose only unstable mode is its rigid
  rotation keeps its exact M̂ (a full Newton step) instead of falling back to level 1.
- Indefinite exact matrices (``set_indefinite``, by the caller for a step attempt): the exact
  M̂ is kept with negative pivots (level 0, none zero). A pressed body's boundary nodes wrinkle
  (the volumetric geometric stiffness) in modes its active contacts hold: the Newton step is
  then that of the KKT system [M̂ −C; Cᵀ 0], C the held direction and the active contact rows,
  which the caller solves on the contacts (compute.stepping.active_set) and whose definiteness
  on Cᵀ v = 0 it checks: the active Delassus block must have ``expected_negative()`` negative
  eigenvalues (the same Haynsworth count).
"""

from __future__ import annotations

import numba
import numpy as np

from compute.errors import StepFailure
from compute.fem.ldl import SymbolicLDL, block_offsets


class IndefiniteMatrix(StepFailure):
    """No stabilisation level makes M̂ positive definite for the bodies ``bodies`` (k,) (indices
    in the group)."""

    def __init__(self, bodies: np.ndarray, shift: float):
        self.bodies = bodies
        super().__init__("the Newton matrix M + h^2 theta^2 K_t is not positive definite, even without its "
                         f"volumetric geometric part and with a mass-proportional stiffness {shift:g} mu/(rho R^2)")


class NewtonMatrices:
    """Factorised M̂ of the B bodies of a :class:`compute.fem.batch.BodyBatch`.

    ``level`` (B,) the stabilisation level of each kept factorisation; ``factorizations`` and
    ``stabilised`` count the numeric factorisations done (statistics)."""

    SHIFTS = (0.1, 1.0, 10.0)  # levels 2, 3, 4

    def __init__(self, batch):
        self.batch = batch
        self.symbolic = SymbolicLDL(batch.indptr, batch.indices)
        B, n, nnz = batch.B, batch.n_dof, batch.indices.size
        self.lx = np.zeros((B, self.symbolic.nnz_l))
        self.d = np.zeros((B, n))
        self.data = np.zeros((B, nnz))   # the unmodified M̂ values of each kept factorisation
        self.scale = np.zeros(B)
        self.valid = np.zeros(B, bool)
        self.level = np.zeros(B, np.int64)
        self.version = np.zeros(B, np.int64)  # bumped at every refactorisation of a body
        self.key = None
        radius2 = batch.reference_areas.sum(axis=1) / np.pi
        m = batch.material
        self._unit = m.mu / (m.density * radius2)  # μ / (ρ R²) (B,)
        self._blocks = None  # (start, dofs, versions, values) of the last compliance blocks
        self.held = None  # c (B, n) of hold(), or None
        self._z = np.zeros((B, n))  # M̂⁻¹ c of the kept factorisations
        self._s = np.ones(B)  # cᵀ M̂⁻¹ c
        self.negative = np.zeros(B, np.int64)  # negative pivots of the kept factorisations
        self.allow_indefinite = False
        self.factorizations = 0
        self.stabilised = 0

    def update(self, data, geometric, key, change_limit: float, force, active) -> np.ndarray:
        """Factorise M̂ (values ``data`` (B, nnz)) of the active bodies whose kept factorisation
        is not valid any more (see the module docstring). ``geometric(mask)`` returns (B, nnz)
        values of h²θ² G for the bodies in ``mask`` (computed only if some body needs a
        fallback). Returns the mask (B,) of refactorised bodies; raises IndefiniteMatrix for the
        bodies for which no level is positive definite."""
        same = key == self.key
        need = active & ~self.valid
        if same:
            change = _max_abs_change(data, self.data, active)
            need |= active & (force | (change > change_limit * self.scale))
        else:
            need = active.copy()
        if not need.any():
            return need
        h, theta = key
        start = np.where(same, self.level, 0)
        pending = need.copy()
        values = data  # level 0; a modified copy for the fallback levels
        g = None
        for level in range(2 + len(self.SHIFTS)):
            trying = pending & (start <= level)
            if not trying.any():
                continue
            if level > 0:
                if g is None:
                    g = geometric(pending)
                    values = data.copy()
                values[trying] = data[trying] - g[trying]
                if level > 1:
                    shift = self.SHIFTS[level - 2] * (h * theta) ** 2 * self._unit / self.batch.mass_scale  # of M unscaled
                    values[trying] += shift[trying, None] * self.batch.mass_data[trying]
            negative = self.symbolic.factorize(values, trying, self.lx, self.d)
            self.factorizations += int(trying.sum())
            self._bordered(trying & (negative >= 0))
            done = trying & self._definite(negative)
            if level == 0 and self.allow_indefinite:
                done |= trying & (negative > 0)
            self.negative[done] = negative[done]
            self.level[done] = level
            if level > 0:
                self.stabilised += int(done.sum())
            pending &= ~done
            if not pending.any():
                break
        if pending.any():
            self.valid[pending] = False
            raise IndefiniteMatrix(np.flatnonzero(pending), self.SHIFTS[-1])
        self.data[need] = data[need]
        self.scale[need] = np.abs(data[need]).max(axis=1)
        self.valid[need] = True
        self.version[need] += 1
        self.key = key
        return need

    def hold(self, c: np.ndarray | None) -> None:
        """Hold the direction c_b (B, n) of every body from now on (module docstring), or no
        direction (None). Kept factorisations that are not definite on the new held subspace
        become invalid (the next update refactorises them); every compliance block changes."""
        self.held = None if c is None else np.ascontiguousarray(c, dtype=np.float64)
        self._bordered(self.valid)
        self.valid &= self._definite(self.negative) | self.indefinite()
        self.version += 1

    def set_indefinite(self, allowed: bool) -> None:
        """Allow indefinite exact factorisations from now on (kept ones at a stabilised level are
        redone from level 0), or no longer (kept indefinite ones are dropped)."""
        if allowed:
            self.valid &= self.level == 0
            self.level[:] = 0
        else:
            self.valid &= ~self.indefinite()
        self.allow_indefinite = allowed

    def indefinite(self) -> np.ndarray:
        """(B,) bodies whose kept factorisation is an indefinite M̂ (``set_indefinite``)."""
        return self.valid & (self.level == 0) & (self.negative > 0)

    def expected_negative(self) -> np.ndarray:
        """(B,) negative eigenvalues the active Delassus block of each body must have for its
        Newton step to be definite on the constraints (module docstring): its negative pivots,
        less the one the held direction takes (s < 0)."""
        held = self.held is not None
        return np.where(self.valid, self.negative - (held & (self._s < 0.0) & (self.negative > 0)), 0)

    def _bordered(self, bodies: np.ndarray) -> None:
        """z = M̂⁻¹ c and s = cᵀ z of the held direction for ``bodies`` (B,) from their current
        factors (nothing without a hold)."""
        if self.held is not None and bodies.any():
            self.symbolic.solve(self.lx, self.d, self.held, bodies, self._z)
            self._s[bodies] = np.einsum("ij,ij->i", self.held[bodies], self._z[bodies])

    def _definite(self, negative: np.ndarray) -> np.ndarray:
        """(B,) whether each factorisation with ``negative`` pivots is positive definite on the
        velocities it acts on: all of them, or with a hold those with cᵀ v = 0 (module docstring)."""
        if self.held is None:
            return negative == 0
        return (negative == 0) | ((negative == 1) & (self._s < 0.0))

    def forget(self) -> None:
        """Drop every kept factorisation, level and compliance block: the next update starts as
        a new group does (what a run resumed from a checkpoint starts from)."""
        self.valid[:] = False
        self.key = None
        self._blocks = None

    def solve(self, rhs: np.ndarray, active: np.ndarray, v: np.ndarray | None = None) -> np.ndarray:
        """M̂_b⁻¹ rhs_b (B, n) for the active bodies (zeros elsewhere); with a hold G rhs_b, plus
        z (cᵀ v_b) / s if velocities ``v`` (B, n) are given, so that v − solve(R(v), v) is the
        Newton step's end with cᵀ v = 0 (module docstring)."""
        out = np.zeros_like(rhs)
        self.symbolic.solve(self.lx, self.d, rhs, active, out)
        if self.held is not None:
            ct = np.einsum("ij,ij->i", self._z, rhs)
            if v is not None:
                ct -= np.einsum("ij,ij->i", self.held, v)
            out -= np.where(active, ct / self._s, 0.0)[:, None] * self._z
        return out

    def compliance(self, start: np.ndarray, dofs: np.ndarray) -> np.ndarray:
        """Blocks C_b = E_bᵀ M̂_b⁻¹ E_b, row-major and concatenated (offsets ``block_offsets(start)``),
        for the local dofs ``dofs[start[b]:start[b + 1]]`` of every body; blocks whose body kept
        its factorisation and its dofs since the last call are copied, not recomputed."""
        offsets = block_offsets(start)
        values = np.zeros(offsets[-1])
        recompute = np.diff(start) > 0
        if self._blocks is not None:
            old_start, old_dofs, old_version, old_values = self._blocks
            kept = _same_segments(start, dofs, old_start, old_dofs) & (old_version == self.version) & recompute
            _copy_blocks(kept, block_offsets(old_start), old_values, offsets, values)
            recompute &= ~kept
        if recompute.any():
            self.symbolic.compliance(self.lx, self.d, start, dofs, recompute, values)
            if self.held is not None:
                _subtract_outer(recompute, start, dofs, offsets, self._z, 1.0 / self._s, values)
        self._blocks = (start, dofs, self.version.copy(), values)
        return values


@numba.njit(cache=True)
def _max_abs_change(a, b, active):
    """max_j |a[i, j] - b[i, j]| (B,) over the active rows (0 elsewhere)."""
    out = np.zeros(a.shape[0])
    for i in range(a.shape[0]):
        if active[i]:
            m = 0.0
            for j in range(a.shape[1]):
                m = max(m, abs(a[i, j] - b[i, j]))
            out[i] = m
    return out


@numba.njit(cache=True)
def _same_segments(start, dofs, old_start, old_dofs):
    """(B,) True where segment b of the ragged ``dofs`` equals segment b of ``old_dofs``."""
    B = start.shape[0] - 1
    out = np.zeros(B, np.bool_)
    for b in range(B):
        m = start[b + 1] - start[b]
        if m != old_start[b + 1] - old_start[b]:
            continue
        same = True
        for k in range(m):
            if dofs[start[b] + k] != old_dofs[old_start[b] + k]:
                same = False
                break
        out[b] = same
    return out


@numba.njit(cache=True)
def _subtract_outer(bodies, start, dofs, offsets, z, weight, values):
    """Block b of ``values`` -= weight_b z_b[d] z_b[d]ᵀ, d = dofs[start[b]:start[b + 1]], for the
    bodies with bodies[b] (the rank-one part of a held compliance block)."""
    for b in range(bodies.shape[0]):
        if bodies[b]:
            m = start[b + 1] - start[b]
            for i in range(m):
                zi = weight[b] * z[b, dofs[start[b] + i]]
                for j in range(m):
                    values[offsets[b] + i * m + j] -= zi * z[b, dofs[start[b] + j]]


@numba.njit(cache=True)
def _copy_blocks(kept, old_offsets, old_values, offsets, values):
    for b in range(kept.shape[0]):
        if kept[b]:
            size = offsets[b + 1] - offsets[b]
            for k in range(size):
                values[offsets[b] + k] = old_values[old_offsets[b] + k]
