r"""Soft bodies: all deformable bodies sharing one reference mesh connectivity and material,
batched (arrays shaped (bodies, nodes, 2)).

Each body is total-Lagrangian, plane strain, neo-Hookean (:mod:`compute.fem`). Over a step of
size h with θ, for every body b and the Newton iterate v of its end-of-step velocity:

    x_θ = x_n + θ h ((1 - θ) v⁻ + θ v)
    R_b(v) = M_b (v - v⁻) + h f_int(x_θ) - h M_b g                                   (residual)
    M̂_b = ∂R_b/∂v = M_b + h²θ² K_t(x_θ)
    v_free,b = v - M̂_b⁻¹ R_b(v)                      (the body's free velocity at this iterate)
    v_b = v_free,b + M̂_b⁻¹ (H r)_b                     (interior recovery after the contact solve)

At convergence R_b(v) = (H r)_b exactly, whatever matrix the iterations used.

With ``hold_rotation`` (the scene's ``solver.hold_rotation``) each body's angular momentum about
its centroid at x_n is held at zero by a multiplier λ_b (a torque), c_b = M_b ρ_b with ρ_b the
rigid rotation field about that centroid:

    R_b(v) = (H r)_b + c_b λ_b,     c_bᵀ v = 0

(NewtonMatrices.hold: the solves and compliance blocks become those of the bordered system).
It removes the one mode that frictionless contacts leave free, the rigid rotation of a pressed
body, which its compressive loads make unstable: without it the iteration needs a stabilised
matrix and converges linearly; with it the exact M̂ is definite on what is left.

A step solved by compute.stepping.active_set (``use_indefinite``) takes the exact M̂ even
where the boundary's wrinkling modes make it indefinite: the active contacts hold them.

The factorised matrices live in :class:`~compute.bodies.soft_matrix.NewtonMatrices`. Bodies
whose own correction fell below the Newton tolerance are *settled*: their residual, tangent and
factorisation are not recomputed in the following iterations of the step (a chord step for
them; the free velocity of the last evaluation stays valid to first order in their remaining
correction).

Mass scaling (the scene's ``solver.mass_scaling`` c, :func:`mass_scale`): in a pressure stage P
the bodies' inertia is s = max(1, c P h² / (ρ ⟨d⟩²)) times their material's, gravity's weight
left as it is. Why: pressure makes K_t indefinite, and at a large h the inertia M / (hθ)² no
longer covers it. Along a pressed disk's linearised rotation, for one, the internal work falls
by 2 p A ω² against the kinetic ρ A r² ω² / (2 h²) (θ = 1): M̂ stays positive definite only while
ρ > 16 p h² / d². Where it is not, the Newton iteration falls back to a stabilised matrix,
converges linearly and the steps are cut. Static equilibria do not depend on the mass, and the
stages end on equilibria: the scaling changes the path between them (the stage ends it moves
and what it saves: benchmarks/results/mass_scaling.md). The scale is set when a stage starts
(compute.run), from the stage's pressure, so a resumed run sets the same.

The centre of a body (branch vectors, frames) is its current centroid; its area the exact
current area of its elements.
"""

from __future__ import annotations

import numpy as np

from compute.errors import StepFailure
from compute.bodies.soft_matrix import IndefiniteMatrix, NewtonMatrices
from compute.bodies.step_records import SoftStep
from compute.fem.batch import BodyBatch
from compute.threads import sized_to_group
from compute.timing import TIMES


class SoftBodies:
    """B soft bodies of one mesh and material. ``ids`` (B,) global body ids; ``material`` the
    scene's material index; ``dof0`` the first dof (body b, node a: dof0 + 2 (b n + a) + (0, 1));
    ``node0`` the index of its first node among all soft nodes of the model."""

    kind = "soft"
    nonlinear = True
    REFACTOR_CHANGE = 0.05  # refactorise when max |M̂ - M̂_factorised| > this x max |M̂_factorised|
    EXACT_CHANGE = 1e-3  # the same after refresh() (a Newton iteration, compute.stepping.active_set)

    def __init__(self, ids, X, cells, element: str, material, volumetric: str, material_index: int,
                 dof0: int, node0: int, hold_rotation: bool = False):
        self.ids = np.asarray(ids, np.int64)
        self.batch = BodyBatch(np.asarray(X, float), cells, element, material, volumetric)
        self.matrices = None  # NewtonMatrices, built at the first step (not needed for measures)
        self.material = material_index
        self.B, self.n_nodes = self.batch.B, self.batch.n_nodes
        self.dof0, self.node0 = dof0, node0
        self.dofs = slice(dof0, dof0 + 2 * self.B * self.n_nodes)
        nb = len(self.batch.boundary)
        self.loop_nodes = (node0 + self.n_nodes * np.arange(self.B)[:, None] + self.batch.boundary).ravel()
        self.loop_start = nb * np.arange(self.B + 1)
        self._gravity = None  # (gravity, M g (B, 2n)) of the last step
        self._f = self._k = None  # work arrays of the Newton iterations, allocated at the first step
        self.hold_rotation = hold_rotation

    def __len__(self) -> int:
        return self.B

    def scale_mass(self, factor: float) -> None:
        """Inertia ``factor`` times the material's (:func:`mass_scale`); the Newton matrices
        kept so far are dropped when it changes (they start again from the exact M̂)."""
        if factor != self.batch.mass_scale:
            self.batch.scale_mass(factor)
            if self.matrices is not None:
                self.matrices.forget()

    def nodes(self, a: np.ndarray) -> np.ndarray:
        """(B, n_nodes, 2) view of this group's part of q or v."""
        return a[self.dofs].reshape(self.B, self.n_nodes, 2)

    def initial(self, q: np.ndarray) -> None:
        self.nodes(q)[:] = self.batch.X

    # --- the step -------------------------------------------------------------------------
    @sized_to_group
    def begin_step(self, q, v, h, theta, load) -> SoftStep:
        """The step's record (compute.bodies.step_records.SoftStep) at positions q and velocities
        v (n_dofs,): what its Newton iterations read (x_n, v⁻, J_n, M g) and change."""
        if self.matrices is None:
            self.matrices = NewtonMatrices(self.batch)
        g = tuple(load.gravity)
        if self._gravity is None or self._gravity[0] != g:  # M g, kept while gravity does not change
            self._gravity = (g, self.batch.mass_times(np.tile(np.asarray(g, float), (self.B, self.n_nodes)),
                                                      material=True))
        x_n = self.nodes(q).copy()
        v_n = v[self.dofs].reshape(self.B, -1).copy()
        if self.hold_rotation:
            self.matrices.hold(self.rotation_momenta(x_n))
        if self._f is None:  # work arrays of the Newton iterations
            self._f = np.zeros_like(v_n)
            self._k = np.zeros_like(self.batch.mass_data)
        return SoftStep(h, theta, x_n, v_n, self.batch.jacobians(x_n), self._gravity[1], np.zeros_like(v_n),
                        settled=np.zeros(self.B, bool), force=np.zeros(self.B, bool), stale=np.zeros(self.B, bool))

    def positions(self, step: SoftStep, v_b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(x_θ, x_new), both (B, n, 2), for end-of-step velocities v_b (B, 2n)."""
        h, th = step.h, step.theta
        dx = h * ((1.0 - th) * step.v_n + th * v_b).reshape(self.B, self.n_nodes, 2)
        return step.x_n + th * dx, step.x_n + dx

    @sized_to_group
    def free_velocity(self, step: SoftStep, v, out) -> None:
        """v_free = v - M̂⁻¹ R(v) of every unsettled body (module docstring), written to ``out``.

        The tangent (and so the check whether a kept factorisation is still close to M̂) is
        evaluated at the first iteration of a step, and later only for the bodies that must
        refactorise (no valid factorisation, or forced after a slow contraction); the other
        iterations need the internal force only."""
        step.iteration += 1
        h, th, batch = step.h, step.theta, self.batch
        vb = v[self.dofs].reshape(self.B, -1)
        active = ~step.settled
        if active.any():
            x_theta, _ = self.positions(step, vb)
            f, k = self._f, self._k
            tangent = active & (step.force | ~self.matrices.valid) if step.iteration > 1 and not step.exact else active
            limit = self.EXACT_CHANGE if step.exact else self.REFACTOR_CHANGE
            step.exact = False
            with TIMES("assembly"):
                ok = batch.internal_force_and_tangent(x_theta, tangent, f, k)
                ok &= batch.internal_force(x_theta, active & ~tangent, f)
            if not ok.all():
                b = int(np.flatnonzero(~ok)[0])
                raise StepFailure(self._inverted(step, b, x_theta, "x_theta"))
            residual = self.residual(step, vb, f)
            if not np.isfinite(residual[active]).all():
                b = int(np.flatnonzero(active & ~np.isfinite(residual).all(axis=1))[0])
                raise StepFailure(f"body {self.ids[b]}: non-finite internal forces (Newton iteration {step.iteration})")
            batch.effective_matrix(k, (h * th) ** 2, tangent)  # k <- M + h²θ² K_t on those rows

            def geometric(mask, x_theta=x_theta):
                g = np.zeros_like(batch.mass_data)
                batch.volumetric_geometric(x_theta, mask, g)
                return (h * th) ** 2 * g

            try:
                with TIMES("factorisation"):
                    refactored = self.matrices.update(k, geometric, (h, th), limit, step.force, tangent)
            except IndefiniteMatrix as exc:
                b = int(exc.bodies[0])
                ratio = (batch.jacobians(x_theta)[b] / step.j_n[b]).min(axis=1)
                worst = np.argsort(ratio)[:5]
                raise StepFailure(f"body {', '.join(str(i) for i in self.ids[exc.bodies][:10])}: {exc}; its most "
                                  f"compressed elements {worst.tolist()} (J/J_n down to {ratio[worst[0]]:.3g}) "
                                  f"(Newton iteration {step.iteration}, h = {h:.4g})") from None
            step.stale = active & ~refactored
            step.force[:] = False
            with TIMES("solves"):
                correction = self.matrices.solve(residual, active, vb)
            step.v_free[active] = vb[active] - correction[active]
        out[self.dofs] = step.v_free.ravel()

    def momentum_residual(self, step: SoftStep, v: np.ndarray) -> np.ndarray:
        """R_b(v) (B, 2n) of every body at velocities v (n_dofs,), its internal forces evaluated
        at x_θ (no tangent, nothing kept); raises StepFailure where an element inverts."""
        vb = v[self.dofs].reshape(self.B, -1)
        x_theta, _ = self.positions(step, vb)
        f = np.zeros_like(vb)
        ok = self.batch.internal_force(x_theta, np.ones(self.B, bool), f)
        if not ok.all():
            raise StepFailure(self._inverted(step, int(np.flatnonzero(~ok)[0]), x_theta, "x_theta"))
        return self.residual(step, vb, f)

    def hold_torques(self, step: SoftStep, v: np.ndarray, hr: np.ndarray) -> np.ndarray:
        """(B,) the torque the rotation hold applies to each body over the step, relative to the
        moments of its contact forces about its centroid: |ρᵀ (R(v) − H r)| / Σ_a |x_a − x̄| |(H r)_a|
        (angular impulses; ρ the rotation field about the centroid at x_n); 0 without a hold,
        inf for a body without contact that the hold turns. v (n_dofs,) end-of-step velocities,
        hr (n_dofs,) the contact impulses H r."""
        if not self.hold_rotation:
            return np.zeros(self.B)
        arm, rho = self._rotation_field(step.x_n)
        contact = hr[self.dofs].reshape(self.B, -1)
        held = np.abs(np.einsum("ij,ij->i", rho, self.momentum_residual(step, v) - contact))
        scale = np.sum(np.linalg.norm(arm, axis=2) * np.linalg.norm(contact.reshape(self.B, -1, 2), axis=2), axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(scale > 0.0, held / np.where(scale > 0.0, scale, 1.0), np.where(held > 0.0, np.inf, 0.0))

    def residual(self, step: SoftStep, vb: np.ndarray, f: np.ndarray) -> np.ndarray:
        """R_b(v) = M_b (v - v⁻) + h f_int - h M_b g (B, 2n) of every body, for its velocities
        vb (B, 2n) and internal forces f (B, 2n) at x_θ (module docstring)."""
        return self.batch.mass_times(vb - step.v_n) + step.h * f - step.h * step.gravity

    def rotation_momenta(self, x: np.ndarray) -> np.ndarray:
        """c_b = M_b ρ_b (B, 2n): ρ_b the rigid rotation field of body b about its centroid in
        positions x (B, n, 2), so that c_bᵀ v_b is its angular momentum about that centroid."""
        return self.batch.mass_times(self._rotation_field(x)[1])

    def _rotation_field(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Arms x − x̄ (B, n, 2) from each body's centroid in positions x (B, n, 2), and the rigid
        rotation field ρ = e_z × (x − x̄) (B, 2n) about it."""
        arm = x - self.batch.centroids(x)[:, None, :]
        return arm, np.stack([-arm[..., 1], arm[..., 0]], axis=2).reshape(self.B, -1)

    def held_directions(self) -> np.ndarray | None:
        """c (B, 2n) of the rotation hold of this step (NewtonMatrices.hold), or None."""
        return self.matrices.held

    def use_indefinite(self, on: bool) -> None:
        """Whether the next factorisations may be indefinite (NewtonMatrices.set_indefinite)."""
        self.matrices.set_indefinite(on)

    def indefinite(self) -> np.ndarray:
        """(B,) bodies whose kept factorisation is an indefinite exact M̂ (use_indefinite)."""
        return self.matrices.indefinite() if self.matrices is not None else np.zeros(self.B, bool)

    def expected_negative(self) -> int:
        """Negative eigenvalues the active Delassus operator must have from this group's bodies
        for the Newton step to be definite on the constraints (NewtonMatrices.expected_negative)."""
        return int(self.matrices.expected_negative()[self.indefinite()].sum())

    def factorisation_stamp(self) -> int:
        """Changes whenever some body of the group refactorises (compliance blocks to redo)."""
        return int(self.matrices.version.sum())

    def factorisation_counts(self) -> tuple[int, int]:
        """(numeric factorisations, stabilised ones) done so far by the group (statistics)."""
        m = self.matrices
        return (m.factorizations, m.stabilised) if m is not None else (0, 0)

    def forget_factorisations(self) -> None:
        """Start the next step without reused factorisations (see Stepper.restart_point)."""
        if self.matrices is not None:
            self.matrices.forget()

    def refresh(self, step: SoftStep) -> None:
        """The next free_velocity assembles the tangent of every unsettled body and refactorises
        those whose M̂ changed by more than EXACT_CHANGE of its largest entry (a Newton iteration,
        not a chord one through changes of up to REFACTOR_CHANGE). Why not 0: far fewer
        factorisations for a few more Newton iterations
        (benchmarks/results/active_set_single_particle.md, figures in design_figures.md)."""
        step.exact = True

    def contraction_was_slow(self, step: SoftStep) -> None:
        """The last iteration contracted the correction too little: the bodies that kept an old
        factorisation refactorise at the next one."""
        step.force |= step.stale

    def settle(self, step: SoftStep, v_old, v_new, tol: float) -> None:
        """Mark the bodies whose position correction h θ |v_new - v_old| is below ``tol``."""
        step.settled |= self.corrections(step, v_old, v_new) <= tol

    def corrections(self, step: SoftStep, v_old, v_new) -> np.ndarray:
        """(B,) position correction h θ max |v_new - v_old| of each body of the group."""
        return step.h * step.theta * np.abs(v_new[self.dofs] - v_old[self.dofs]).reshape(self.B, -1).max(axis=1)

    @sized_to_group
    def compliance(self, step: SoftStep, dofs: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Dense blocks of M̂⁻¹ on the contact dofs ``dofs`` (sorted, unique, all in this group):
        (start (B + 1,), dofs (m,) global, values) in the layout of
        :meth:`compute.contact.compliance.Compliance.build`."""
        local = dofs - self.dof0
        n = 2 * self.n_nodes
        start = np.searchsorted(local, n * np.arange(self.B + 1)).astype(np.int64)
        values = self.matrices.compliance(start, (local % n).astype(np.int64))
        diag = _block_diagonals(start, values)
        bad = ~(diag > 0.0) & ~np.repeat(self.matrices.indefinite(), np.diff(start))  # those are checked later
        if bad.any():
            b = int(np.searchsorted(start, np.flatnonzero(bad)[0], side="right") - 1)
            raise StepFailure(f"body {self.ids[b]}: effective matrix M + h^2 theta^2 K_t not positive definite on "
                              f"its contact dofs (Newton iteration {step.iteration}, h = {step.h:.4g})")
        return start, dofs, values

    @sized_to_group
    def compliance_times(self, hr) -> np.ndarray:
        """M̂_b⁻¹ (H r)_b (B, 2n) of every body (zeros for bodies without a contact impulse)."""
        rhs = hr[self.dofs].reshape(self.B, -1)
        touched = np.any(rhs != 0.0, axis=1)
        return self.matrices.solve(rhs, touched) if touched.any() else np.zeros_like(rhs)

    @sized_to_group
    def area_change(self, step: SoftStep, v, lo: float, hi: float):
        """None if every element keeps J / J_n within [lo, hi] at x_θ and x_new for velocities v;
        else (body id, elements (k,), smallest ratio) of the first body that does not."""
        x_theta, x_new = self.positions(step, v[self.dofs].reshape(self.B, -1))
        for x in (x_theta,) if step.theta == 1.0 else (x_theta, x_new):
            span = self.batch.jacobian_ratio_range(x, step.j_n)
            bad = ~((span[:, 0] >= lo) & (span[:, 1] <= hi))
            if bad.any():
                b = int(np.flatnonzero(bad)[0])
                ratio = self.batch.jacobians(x)[b] / step.j_n[b]
                els = np.flatnonzero(~((ratio >= lo) & (ratio <= hi)).all(axis=1))
                return int(self.ids[b]), els, float(np.nanmin(ratio))
        return None

    # --- measures ---------------------------------------------------------------------------
    @sized_to_group
    def centres(self, q) -> np.ndarray:
        return self.batch.centroids(self.nodes(q))

    @sized_to_group
    def area(self, q) -> float:
        return float(self.batch.areas(self.nodes(q)).sum())

    def bounding_circles(self, q) -> tuple[np.ndarray, np.ndarray]:
        """Centres (B, 2) (mean of the boundary nodes) and radii (B,) of circles holding each
        body's boundary loop."""
        xb = self.nodes(q)[:, self.batch.boundary]
        c = xb.mean(axis=1)
        return np.ascontiguousarray(c), np.sqrt(np.max(np.sum((xb - c[:, None]) ** 2, axis=2), axis=1))

    @sized_to_group
    def kinetic_energy(self, v) -> float:
        return self.batch.kinetic_energy(v[self.dofs].reshape(self.B, -1))

    def meshes(self, q) -> dict:
        """{body id: (points (n, 2), cells, element name)} in the current configuration."""
        x = self.nodes(q)
        return {int(i): (x[b].copy(), self.batch.cells, self.batch.element.name) for b, i in enumerate(self.ids)}

    @sized_to_group
    def frame_fields(self, q, v) -> tuple[dict, dict]:
        """Point fields {name: (B, n, 3)} and cell fields {name: (B, n_elem, ...)}."""
        x, w = self.nodes(q), self.nodes(v)
        z = np.zeros((self.B, self.n_nodes, 1))
        cauchy, pressure, mises = self.batch.element_stresses(x)
        ne = self.batch.cells.shape[0]
        point = {"displacement": np.concatenate([x - self.batch.X, z], axis=2), "velocity": np.concatenate([w, z], axis=2)}
        cell = {"rotation": np.zeros((self.B, ne)), "angular_velocity": np.zeros((self.B, ne)),
                "cauchy_stress": cauchy.reshape(self.B, ne, 9), "pressure": pressure, "von_mises": mises}
        return point, cell

    # --- diagnoses ---------------------------------------------------------------------------
    def _inverted(self, step: SoftStep, b: int, x: np.ndarray, where: str) -> str:
        """Diagnosis of body b's inverted elements in the group's positions x (B, n, 2)."""
        els = np.flatnonzero(~(self.batch.jacobians(x)[b] > 0.0).all(axis=1))
        return (f"body {int(self.ids[b])}: {els.size} inverted element(s) at {where} "
                f"{els[:10].tolist()}{' ...' if els.size > 10 else ''} (Newton iteration {step.iteration}, "
                f"h = {step.h:.4g})")


def mass_scale(coefficient: float, pressure: float, h: float, density: float, diameter: float) -> float:
    """Inertia factor s = max(1, c P h² / (ρ ⟨d⟩²)) of soft bodies of ``density`` in a stage at
    ``pressure`` with time step ``h`` and mean diameter ``diameter`` (module docstring); 1 for
    ``coefficient`` c = 0."""
    return max(1.0, coefficient * pressure * h * h / (density * diameter * diameter))


def _block_diagonals(start: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Diagonal entries (m,) of the row-major blocks ``values`` of sizes diff(start)."""
    sizes = np.diff(start)
    offsets = np.concatenate([[0], np.cumsum(sizes**2)])
    pos = np.arange(start[-1]) - np.repeat(start[:-1], sizes)
    return values[np.repeat(offsets[:-1], sizes) + pos * (np.repeat(sizes, sizes) + 1)]
