r"""Deformable disks in the NSCD loop: the model (dofs, measures, fields) and its stepper.

Model. q, v = [rigid (x, y, rot)]*nr + [4 walls] + [deformable nodes (x, y)]* (compute.state);
each deformable body is a :class:`compute.fem.FEBody` (total Lagrangian, plane strain,
neo-Hookean). Its centre (branch vectors, frames) is its current centroid, its area the exact
current area of its elements.

Step (:class:`DeformableStepper`), with h, theta; for every deformable body b

    R_b(v) = M_b (v - v^-) + h f_int(x_theta(v)) - h f_ext,    x_theta = x_n + theta h ((1-theta) v^- + theta v)
    M_hat_b = dR_b/dv = M_b + h^2 theta^2 K_t(x_theta)

(rigid disks and walls: the linear Moreau-Jean step of compute.stepper). The contact
conditions (Signorini on the predicted end-of-step gap, Coulomb) are written with the contact
rows H at q_n. Newton iterations k = 0, 1, ... linearise R_b at v^k:

    v_free,b = v^k_b - M_hat_b^-1 R_b(v^k)                       (per body, factorised M_hat_b)
    W = H^T M_hat^-1 H, with M_hat^-1 restricted to contact dofs  (dense boundary blocks)
    NLGS over all contacts -> r, v on contact dofs                (compute.nlgs, warm-started)
    v^{k+1}_b = v_free,b + M_hat_b^-1 (H r)_b                     (interior velocities)

until h theta |v^{k+1} - v^k|_inf <= newton_tolerance x <d> (position correction relative to
the mean diameter), the contact impulses warm-started from one iteration to the next and from
step to step. At convergence R_b(v) = (H r)_b exactly, whatever matrix the iterations used
(a modified Newton converges to the same solution), which the following devices exploit:

- Reuse: a factorisation is kept while M_hat barely changes (largest entry change below
  ``REFACTOR_CHANGE`` of the largest entry, same h and theta); it is redone when an iteration
  with the kept one contracted the correction by less than ``SLOW_CONTRACTION``. The dense
  compliance block C_b = E^T M_hat_b^-1 E on the contact dofs is recomputed only with a new
  factorisation or a new set of contact dofs, by sparse forward substitutions in the
  symmetric (LDL^T) factorisation.
- Positive definiteness: the Delassus operator needs a positive definite M_hat, which a
  pressed body loses at large h: its volumetric geometric stiffness U'(J) d2(area)/dx2 (U' is
  minus the pressure) is indefinite along a pressed boundary (boundary nodes 'wrinkling'
  against the wall, eigenvalues -20 E/(rho R^2) at P/E = 0.25 with 92 T6 elements) and the
  moment of the compressive loads makes the rigid rotation unstable (sum_a x_a . f_a < 0).
  The contacts hold both, so the constrained problem is stable; the factorisation (SuperLU in
  symmetric mode, whose pivots give the inertia) then falls back to M_hat without the
  volumetric geometric stiffness, then adds a mass-proportional stiffness
  (:class:`_BodySolver`). Measured in the single-particle study: with h = 10 every stage
  above P/E = 0.01 uses the first fallback; it converges in 5 to 15 iterations.
- Anderson acceleration (depth ``ANDERSON``) of the fixed-point iteration v -> v^{k+1}
  restores fast convergence when the iteration is a modified Newton.
- Backtracking: a Newton update that would change some element's area by more than a factor
  2 in one step (``JACOBIAN_RATIO``) is halved until it does not (large load increments
  overshoot from a linearised contact solution).

Failures are never silent: an inverted element, a non-finite value, a Newton matrix that no
fallback makes positive definite, or a Newton loop that does not converge in
newton_max_iterations makes the step restart from its initial state with h/2 (two half
steps), up to ``MAX_CUTS`` times; then :class:`compute.errors.SimulationError` names the step,
the body, the elements and h, and the state is left as it was before the step. A step that
needed cuts still advances time by h and counts as one step; its last impulses are rescaled
to the full h so that forces = impulse / h stay right in frames and warm starts.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

import numba
import numpy as np
import scipy.sparse.linalg as spla

from compute import deformable_detection, detection
from compute.compliance import Compliance
from compute.contact_geometry import Contacts
from compute.errors import SceneError, SimulationError
from compute.fem import FEBody, InvertedElementError, NeoHookean
from compute.model import Model
from compute.scene import Scene
from compute.state import Layout, State
from compute.stepper import StepReport, Stepper


# --------------------------------------------------------------------------------- the model


class DeformableModel(Model):
    """Rigid disks, walls and deformable (FE) disks.

    Arrays besides :class:`Model`'s: ``bodies`` list of FEBody (nd); ``deformable_ids`` (nd,)
    global body ids; ``deformable_material`` (nd,); ``node_dof0`` first node dof;
    ``node_start`` (nd + 1,) global node offsets; ``node_body`` (N,) deformable index of each
    global node; ``loop_nodes`` (n_b,) boundary loops (global node ids, CCW, body after body)
    with offsets ``loop_start`` (nd + 1,).
    """

    def __init__(self, scene: Scene):
        super().__init__(scene)
        nr = self.layout.n_rigid
        self.bodies: list[FEBody] = []
        for d in scene.deformable:
            m = scene.materials[scene.material_names[scene.body_material[d.body]]]
            try:
                body = FEBody(d.points, d.cells, d.element, NeoHookean(m.young, m.poisson, m.density),
                              m.volumetric)
            except ValueError as exc:
                raise SceneError(scene.path / "bodies.vtu", f"cells of body {d.body}",
                                 "a valid counter-clockwise disk mesh", str(exc)) from None
            self.bodies.append(body)
        nd = len(self.bodies)
        self.deformable_ids = np.array([d.body for d in scene.deformable], dtype=np.int64)
        self.deformable_material = scene.body_material[self.deformable_ids].astype(np.int64)
        counts = np.array([b.n_nodes for b in self.bodies], dtype=np.int64)
        self.node_dof0 = 3 * nr + 4
        self.node_start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        offsets = self.node_dof0 + 2 * self.node_start[:-1]
        self.layout = Layout(nr, tuple(int(o) for o in offsets), tuple(int(c) for c in counts))
        self.node_body = np.repeat(np.arange(nd), counts).astype(np.int64)
        loops = [b.boundary + self.node_start[k] for k, b in enumerate(self.bodies)]
        self.loop_nodes = np.concatenate(loops).astype(np.int64)
        self.loop_start = np.concatenate([[0], np.cumsum([len(lp) for lp in loops])]).astype(np.int64)
        self._loop_body = np.repeat(np.arange(nd), np.diff(self.loop_start))
        self._reference = np.concatenate([b.X for b in self.bodies])

    def make_stepper(self):
        return DeformableStepper(self)

    # --- views ---------------------------------------------------------------------------
    def node_positions(self, q: np.ndarray) -> np.ndarray:
        """(N, 2) view of all deformable node positions (or velocities) in q (or v)."""
        return q[self.node_dof0:].reshape(-1, 2)

    def body_nodes(self, a: np.ndarray, k: int) -> np.ndarray:
        """(n_k, 2) view of deformable body k's nodes in q or v."""
        return a[self.layout.body_dofs(k)].reshape(-1, 2)

    def bounding_circles(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Centres (nd, 2) (mean of the boundary nodes) and radii (nd,) of circles holding each
        body's boundary loop, from node positions x (N, 2)."""
        xb = x[self.loop_nodes]
        n = np.diff(self.loop_start)
        c = np.add.reduceat(xb, self.loop_start[:-1], axis=0) / n[:, None]
        d = np.sqrt(np.sum((xb - c[self._loop_body]) ** 2, axis=1))
        return np.ascontiguousarray(c), np.maximum.reduceat(d, self.loop_start[:-1])

    # --- state and measures --------------------------------------------------------------
    def initial_state(self) -> State:
        state = super().initial_state()
        self.node_positions(state.q)[:] = self._reference
        return state

    def body_centres(self, q: np.ndarray) -> np.ndarray:
        c = super().body_centres(q)
        for k, b in enumerate(self.bodies):
            c[self.deformable_ids[k]] = b.centroid(self.body_nodes(q, k))
        return c

    def current_meshes(self, q: np.ndarray) -> dict:
        return {int(self.deformable_ids[k]): (self.body_nodes(q, k).copy(), b.cells, b.element.name)
                for k, b in enumerate(self.bodies)}

    def particle_area(self, q: np.ndarray) -> float:
        return super().particle_area(q) + sum(b.area(self.body_nodes(q, k)) for k, b in enumerate(self.bodies))

    def kinetic_energy(self, v: np.ndarray) -> float:
        e = super().kinetic_energy(v)
        for k, b in enumerate(self.bodies):
            vb = v[self.layout.body_dofs(k)]
            e += 0.5 * float(vb @ (b.mass @ vb))
        return e

    def gravity_forces(self) -> np.ndarray:
        """Rigid and wall part from Model; deformable nodes get the consistent M g."""
        f = super().gravity_forces()
        g = np.asarray(self.scene.loading.gravity, float)
        for k, b in enumerate(self.bodies):
            f[self.layout.body_dofs(k)] = b.mass @ np.tile(g, b.n_nodes)
        return f

    def frame_fields(self, state: State) -> dict:
        fields = super().frame_fields(state)
        point, cell = fields["point"], fields["cell"]
        for name in ("displacement", "velocity"):
            point[name]["deformable"] = {}
        for name in ("rotation", "angular_velocity", "cauchy_stress", "pressure", "von_mises"):
            cell[name]["deformable"] = {}
        for k, b in enumerate(self.bodies):
            i = int(self.deformable_ids[k])
            x, v = self.body_nodes(state.q, k), self.body_nodes(state.v, k)
            z = np.zeros((b.n_nodes, 1))
            point["displacement"]["deformable"][i] = np.hstack([x - b.X, z])
            point["velocity"]["deformable"][i] = np.hstack([v, z])
            s = b.element_stresses(x)
            ne = b.cells.shape[0]
            cell["rotation"]["deformable"][i] = np.zeros(ne)
            cell["angular_velocity"]["deformable"][i] = np.zeros(ne)
            cell["cauchy_stress"]["deformable"][i] = s.cauchy.reshape(ne, 9)
            cell["pressure"]["deformable"][i] = s.pressure
            cell["von_mises"]["deformable"][i] = s.von_mises
        return fields

    def frame_contacts(self, state: State) -> Contacts:
        """All contacts (rigid families, then node-wall, node-disk, node-segment) at the state's
        configuration with the impulses of its memory: what a frame writes."""
        centres = self.body_centres(state.q)
        return Contacts.concatenate([detection.narrow_phase(self, state),
                                     deformable_detection.narrow_phase(self, state, centres)])


# ------------------------------------------------------------------------------ the stepper


class _StepFailure(Exception):
    """A step attempt that must not be accepted (the message is the diagnosis)."""


class _BodySolver:
    """Factorised Newton matrix of one deformable body, kept while it stays valid.

    The factorisation is scipy's SuperLU in symmetric mode (symmetric ordering, no pivoting:
    an LDL^T in disguise), so that the signs of U's diagonal give the matrix's inertia (the
    Delassus operator needs a positive definite matrix). ``level`` is the stabilisation of
    the factorised matrix (see DeformableStepper).
    """

    SHIFTS = (0.1, 1.0, 10.0)  # levels 2, 3, 4: + h^2 theta^2 s mu / (rho R^2) M (last resorts)

    def __init__(self, body: FEBody, dofs: slice):
        self.body, self.dofs = body, dofs
        self.lu = None
        self.data = None
        self.key = None
        self.cache: dict = {}
        self.scale = 1.0
        self.level = 0

    def prepare(self, data: np.ndarray, geometric, key: tuple, change_limit: float, force: bool) -> bool:
        """Factorise M_hat (values ``data`` (nnz,) in the body's CSR pattern) unless the kept
        factorisation is still valid: same key (h, theta) and no entry changed by more than
        change_limit x the largest. If M_hat is not positive definite, factorise the first
        positive definite of M_hat - G (level 1, G = ``geometric()`` (nnz,), the volumetric
        geometric stiffness x h^2 theta^2) and M_hat - G + h^2 theta^2 s mu/(rho R^2) M (levels
        2.., s in SHIFTS, R the body's radius: a stiffness proportional to the mass).
        Returns True if it factorised; raises _StepFailure if none is positive definite."""
        if self.lu is not None and not force and key == self.key:
            if np.max(np.abs(data - self.data)) <= change_limit * self.scale:
                return False
        g = None
        h, theta = key
        b = self.body
        unit = (h * theta) ** 2 * b.material.mu / (b.material.density * b.reference_areas.sum() / np.pi)
        first = self.level if key == self.key else 0  # start where the last factorisation ended
        for level in range(first, 2 + len(self.SHIFTS)):
            if level == 0:
                values = data
            else:
                g = geometric() if g is None else g
                values = data - g if level == 1 else data - g + self.SHIFTS[level - 2] * unit * b.mass.data
            try:
                lu = spla.splu(self.body.csr(values).tocsc(), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                               options=dict(SymmetricMode=True))
            except RuntimeError:  # exactly singular
                continue
            pivots = lu.U.diagonal()
            if np.all(pivots > 0.0):
                break
        else:
            raise _StepFailure("the Newton matrix M + h^2 theta^2 K_t is not positive definite, even without its "
                               f"volumetric geometric part and with a mass-proportional stiffness "
                               f"{self.SHIFTS[-1]:g} mu/(rho R^2)")
        self.lu, self.level, self.pivots = lu, level, pivots
        self._lower = None
        self.data = data.copy()
        self.scale = float(np.max(np.abs(data)))
        self.key = key
        self.cache = {}
        return True

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        return self.lu.solve(rhs)

    def compliance(self, local: np.ndarray) -> np.ndarray:
        """C = E^T M_hat^-1 E (m, m) for the unit columns E of the local dofs (m,).

        With the symmetric factorisation P M_hat P^T = L D L^T (SuperLU in symmetric mode:
        U = D L^T), C = Y^T D^-1 Y with Y = L^-1 P E: only sparse forward substitutions from
        unit vectors (:func:`_unit_lower_columns`), much cheaper than m full solves."""
        key = local.tobytes()
        if key not in self.cache:
            if self._lower is None:
                L = self.lu.L.tocsc()
                self._lower = (L.indptr.astype(np.int64), L.indices.astype(np.int64), L.data)
            rows = self.lu.perm_r[local].astype(np.int64)
            c = _weighted_gram(_unit_lower_columns(*self._lower, rows, self.body.n_dof), 1.0 / self.pivots)
            self.cache = {key: np.ascontiguousarray(0.5 * (c + c.T))}
        return self.cache[key]


@numba.njit(cache=True)
def _weighted_gram(Y, w):
    """C = Y diag(w) Y^T (m, m) for a sparse-in-practice Y (m, n), w (n,)."""
    m, n = Y.shape
    C = np.zeros((m, m))
    idx = np.empty(m, np.int64)
    for k in range(n):
        cnt = 0
        for j in range(m):
            if Y[j, k] != 0.0:
                idx[cnt] = j
                cnt += 1
        for a in range(cnt):
            ya = Y[idx[a], k] * w[k]
            for b in range(cnt):
                C[idx[a], idx[b]] += ya * Y[idx[b], k]
    return C


@numba.njit(cache=True)
def _unit_lower_columns(indptr, indices, data, rows, n):
    """Y (m, n), Y[j] = L^-1 e_rows[j] for L unit lower triangular in CSC (indptr, indices,
    data); entries on or above the diagonal are ignored."""
    m = rows.shape[0]
    Y = np.zeros((m, n))
    for j in range(m):
        y = Y[j]
        y[rows[j]] = 1.0
        for k in range(rows[j], n):
            yk = y[k]
            if yk == 0.0:
                continue
            for idx in range(indptr[k], indptr[k + 1]):
                r = indices[idx]
                if r > k:
                    y[r] -= data[idx] * yk
    return Y


@dataclass
class DeformableStepReport(StepReport):
    newton_iterations: int = 0
    factorizations: int = 0
    cuts: int = 0
    h: float = 0.0


class DeformableStepper(Stepper):
    """Moreau-Jean step with Newton iterations for deformable bodies (module docstring)."""

    MAX_CUTS = 4            # a step may be halved this many times before the run stops
    REFACTOR_CHANGE = 0.05  # refactorise when max |M_hat - M_hat_factorised| > this x max |M_hat_f|
    SLOW_CONTRACTION = 0.25  # ... or when the kept factorisation contracted a correction less

    def __init__(self, model: DeformableModel):
        super().__init__(model)
        self.h_nominal = self.h
        s = model.scene.solver
        self.newton_tolerance = s.newton_tolerance
        self.newton_max_iterations = s.newton_max_iterations
        self.solvers = [_BodySolver(b, model.layout.body_dofs(k)) for k, b in enumerate(model.bodies)]
        self.length = model.diameter
        self.stats = {"steps": 0, "newton_iterations": 0, "factorizations": 0, "cuts": 0, "nlgs_sweeps": 0,
                      "stabilised_factorizations": 0, "backtracks": 0}
        self._step_index = 0
        self._n_rigid_contacts = 0

    # --- the step --------------------------------------------------------------------------
    def step(self, state: State, pressure: float, wall_speed: float = 0.0) -> DeformableStepReport:
        """Advance ``state`` by h (cutting the step when it fails; see the module docstring)."""
        t0, s0, h = state.time, state.step, self.h_nominal
        self._step_index = s0
        snap = _snapshot(state)
        try:
            rep = self._advance(state, pressure, wall_speed, h, 0)
        except SimulationError:
            _restore(state, snap)
            raise
        finally:
            self.h = h
        state.time, state.step = t0 + h, s0 + 1
        if rep.h != h:  # impulses of the last sub-step, over rep.h: rescale to forces x h
            for fam in state.impulses:
                state.impulses[fam] = state.impulses[fam] * (h / rep.h)
            rep.contacts.impulse *= h / rep.h
        self.stats["steps"] += 1
        return rep

    def _advance(self, state, pressure, wall_speed, h, depth) -> DeformableStepReport:
        snap = _snapshot(state)
        try:
            return self._attempt(state, pressure, wall_speed, h)
        except _StepFailure as exc:
            if depth >= self.MAX_CUTS:
                raise SimulationError(f"step {self._step_index + 1}: {exc}; the step was cut {depth} times "
                                      f"(h = {self.h_nominal:.4g} -> {h:.4g}) without success: the load increment "
                                      f"or the time step is too large for this mesh (add intermediate pressure "
                                      f"stages or lower solver.time_step)") from None
            _restore(state, snap)
            self.stats["cuts"] += 1
            first = self._advance(state, pressure, wall_speed, 0.5 * h, depth + 1)
            second = self._advance(state, pressure, wall_speed, 0.5 * h, depth + 1)
            second.sweeps += first.sweeps
            second.newton_iterations += first.newton_iterations
            second.factorizations += first.factorizations
            second.cuts += first.cuts + 1
            return second

    def contacts(self, state: State) -> Contacts:
        """All candidate contacts at q_n: rigid families, then the deformable ones."""
        m = self.model
        if deformable_detection.needs_detection(m, state):
            deformable_detection.detect(m, state)
        rigid = detection.narrow_phase(m, state)
        self._n_rigid_contacts = len(rigid)
        return Contacts.concatenate([rigid, deformable_detection.narrow_phase(m, state)])

    def _attempt(self, state: State, pressure: float, wall_speed: float, h: float) -> DeformableStepReport:
        m, th = self.model, self.theta
        self.h = h
        contacts = self.contacts(state)
        v_free0, diag_dofs, diag = self.free_velocity(state, pressure, wall_speed)
        blocks = self._contact_dofs(contacts)
        v = v_free0.copy()  # deformable part: v^- as the first Newton iterate
        self._j_n = [sol.body.jacobians(m.body_nodes(state.q, k)) for k, sol in enumerate(self.solvers)]
        force = [False] * len(self.solvers)
        stale = [False] * len(self.solvers)
        sweeps_total, n_fact, n_stab, err_prev = 0, 0, 0, np.inf
        tol = self.newton_tolerance * self.length
        history: list = []
        for it in range(1, self.newton_max_iterations + 1):
            v_free = v_free0.copy()
            dense = []
            for k, sol in enumerate(self.solvers):
                d = sol.dofs
                x_n = m.body_nodes(state.q, k)
                try:
                    sys = sol.body.theta_system(v[d], x_n, state.v[d], self.f_gravity[d], self.f_gravity[d], h, th)
                except InvertedElementError as exc:
                    raise _StepFailure(self._inverted(k, exc, "x_theta", it)) from None
                residual_b = sys.residual
                if not np.all(np.isfinite(residual_b)):
                    raise _StepFailure(f"body {m.deformable_ids[k]}: non-finite internal forces "
                                       f"(Newton iteration {it})")
                body, x_theta = sol.body, sys.x_theta

                def geometric(body=body, x_theta=x_theta):
                    return (h * th) ** 2 * body.volumetric_geometric_data(x_theta)

                try:
                    refactored = sol.prepare(sys.matrix.data, geometric, (h, th), self.REFACTOR_CHANGE, force[k])
                except _StepFailure as exc:
                    raise _StepFailure(f"body {m.deformable_ids[k]}: {exc} (Newton iteration {it}, h = {h:.4g})")
                n_stab += refactored and sol.level > 0
                n_fact += refactored
                stale[k] = not refactored
                force[k] = False
                v_free[d] = v[d] - sol.solve(residual_b)
                if k in blocks:
                    local = blocks[k]
                    c = sol.compliance(local)
                    if not np.all(np.diag(c) > 0.0):
                        raise _StepFailure(f"body {m.deformable_ids[k]}: effective matrix M + h^2 theta^2 K_t not "
                                           f"positive definite on its contact dofs (Newton iteration {it}, h = {h:.4g})")
                    dense.append((d.start + local, c))
            comp = Compliance.build(m.layout.n_dofs, diag_dofs, diag, dense)
            try:
                v_new, sweeps, residual = self.solve_contacts(state, contacts, v_free, comp)
            except SimulationError as exc:
                raise _StepFailure(str(exc)) from None
            sweeps_total += sweeps
            self._recover_interior(contacts, blocks, v_free, v_new)
            if not np.all(np.isfinite(v_new)):
                raise _StepFailure(f"non-finite velocities at Newton iteration {it}")
            # convergence on the plain Newton correction G(v) - v (not on an accelerated one)
            err = h * th * float(np.max(np.abs(v_new - v))) if len(v) else 0.0
            if err <= tol:
                v = self._admissible(state, v, v_new, h)
                break
            if self.ANDERSON:
                v_new = self._anderson(history, v, v_new)
            v = self._admissible(state, v, v_new, h)
            if it > 1 and err > 1e6 * max(err_prev, tol):
                raise _StepFailure(f"Newton diverges (position correction {err:.3g} after {err_prev:.3g}, "
                                   f"iteration {it})")
            if err > self.SLOW_CONTRACTION * err_prev:
                force = [f or s for f, s in zip(force, stale)]
            err_prev = err
        else:
            raise _StepFailure(f"Newton did not converge in {self.newton_max_iterations} iterations "
                               f"(last position correction {err:.3g}, tolerance {tol:.3g})")
        self.stats["newton_iterations"] += it
        self.stats["factorizations"] += n_fact
        self.stats["stabilised_factorizations"] += n_stab
        self.stats["nlgs_sweeps"] += sweeps_total
        rep = self.finish(state, v, contacts, sweeps_total, residual)
        return DeformableStepReport(rep.sweeps, rep.residual, rep.n_contacts, rep.max_penetration, rep.contacts,
                                    newton_iterations=it, factorizations=n_fact, cuts=0, h=h)

    def finish(self, state: State, v: np.ndarray, contacts: Contacts, sweeps: int, residual: float) -> StepReport:
        rep = super().finish(state, v, contacts, sweeps, residual)  # rigid memory: the first rows
        deformable_detection.store_impulses(state, contacts.impulse[self._n_rigid_contacts:])
        return rep

    # --- helpers -----------------------------------------------------------------------------
    MAX_BACKTRACKS = 12
    ANDERSON = 4
    JACOBIAN_RATIO = 0.5

    def _anderson(self, history: list, v: np.ndarray, g: np.ndarray) -> np.ndarray:
        """Anderson acceleration of the Newton fixed-point map v -> g = G(v) (depth ANDERSON).

        With a kept or a stabilised factorisation the iteration is a modified Newton, linearly
        convergent; mixing the last iterates (Walker & Ni 2011) restores fast convergence. The
        mixed iterate is G's fixed point when the iteration has converged."""
        history.append((v.copy(), g.copy()))
        if len(history) > self.ANDERSON + 1:
            history.pop(0)
        if len(history) < 2:
            return g
        f = np.array([gi - vi for vi, gi in history])         # (m + 1, n) residuals
        gs = np.array([gi for _, gi in history])
        df = np.diff(f, axis=0).T
        dg = np.diff(gs, axis=0).T
        coef, *_ = np.linalg.lstsq(df, f[-1], rcond=1e-10)
        out = g - dg @ coef
        return out if np.all(np.isfinite(out)) else g

    def _admissible(self, state: State, v: np.ndarray, v_new: np.ndarray, h: float) -> np.ndarray:
        """Backtracking on the Newton update: v + a (v_new - v), a = 1, 1/2, 1/4, ..., the first
        for which every element keeps J(x) / J(x_n) within [JACOBIAN_RATIO, 1 / JACOBIAN_RATIO]
        at x_theta and x_new (a Newton step from a linearised contact solution may overshoot a
        large load increment; no element really changes its area that much in one step). Raises
        _StepFailure if none is found."""
        m, th = self.model, self.theta
        lo, hi = self.JACOBIAN_RATIO, 1.0 / self.JACOBIAN_RATIO
        a = 1.0
        for _ in range(self.MAX_BACKTRACKS):
            trial = v + a * (v_new - v) if a < 1.0 else v_new
            bad = None
            for k, sol in enumerate(self.solvers):
                d = sol.dofs
                x_n = m.body_nodes(state.q, k)
                j_n = self._j_n[k]
                for x in sol.body.theta_positions(x_n, state.v[d], trial[d], h, th)[: 1 if th == 1.0 else 2]:
                    ratio = sol.body.jacobians(x) / j_n
                    worst = ~((ratio >= lo) & (ratio <= hi)).all(axis=1)
                    if worst.any():
                        bad = (k, np.flatnonzero(worst), float(np.nanmin(ratio)))
                        break
                if bad is not None:
                    break
            if bad is None:
                self.stats["backtracks"] += a < 1.0
                return trial
            a *= 0.5
        k, els, r = bad
        raise _StepFailure(f"body {int(m.deformable_ids[k])}: {els.size} element(s) {els[:10].tolist()} would change "
                           f"their area by more than a factor {hi:g} in one step (J/J_n down to {r:.3g}) even "
                           f"after {self.MAX_BACKTRACKS} backtracking halvings of the Newton update (h = {h:.4g})")

    def _contact_dofs(self, contacts: Contacts) -> dict[int, np.ndarray]:
        """{deformable index: sorted local dofs (m,) touched by contact rows}."""
        m = self.model
        d = contacts.dof[contacts.dof >= m.node_dof0]
        if d.size == 0:
            return {}
        d = np.unique(d)
        body = m.node_body[(d - m.node_dof0) // 2]
        out = {}
        for k in np.unique(body):
            out[int(k)] = (d[body == k] - m.layout.node_offsets[k]).astype(np.int64)
        return out

    def _recover_interior(self, contacts: Contacts, blocks: dict, v_free: np.ndarray, v: np.ndarray) -> None:
        """v_b = v_free,b + M_hat_b^-1 (H r)_b for every body with contacts (in place in v)."""
        if not blocks:
            return
        hr = np.zeros(len(v))
        ok = contacts.dof >= 0
        val = contacts.hn * contacts.impulse[:, :1] + contacts.ht * contacts.impulse[:, 1:]
        np.add.at(hr, contacts.dof[ok], val[ok])
        for k in blocks:
            sol = self.solvers[k]
            d = sol.dofs
            v[d] = v_free[d] + sol.solve(hr[d])

    def _inverted(self, k: int, exc: InvertedElementError, where: str, it: int) -> str:
        els = exc.elements
        return (f"body {int(self.model.deformable_ids[k])}: {els.size} inverted element(s) at {where} "
                f"{els[:10].tolist()}{' ...' if els.size > 10 else ''} (Newton iteration {it}, h = {self.h:.4g})")


def _snapshot(state: State):
    return (state.q.copy(), state.v.copy(), state.time, state.step,
            None if state.q_detect is None else state.q_detect.copy(),
            {k: a.copy() for k, a in state.pairs.items()}, {k: a.copy() for k, a in state.impulses.items()})


def _restore(state: State, snap) -> None:
    q, v, t, s, qd, pairs, imp = snap
    state.q, state.v, state.time, state.step = q.copy(), v.copy(), t, s
    state.q_detect = None if qd is None else qd.copy()
    state.pairs = copy.deepcopy(pairs)
    state.impulses = copy.deepcopy(imp)
