"""One Moreau–Jean step: the sequence of a time step, visible in one place.

With h the time step and θ ∈ [1/2, 1]:

    M̂ (v⁺ - v_free) = H r                         (impulse balance)
    v_free = v⁻ + h M̂⁻¹ F(t_n + θh)               (free velocity: gravity, wall loads)
    q⁺ = q⁻ + h ((1 - θ) v⁻ + θ v⁺)                (θ-method on positions)
    r from NLGS with Signorini on g̃ + hθ u_n⁺ and Coulomb on u_t⁺   (see compute.nlgs)

For rigid bodies and walls M̂ is diagonal; deformable bodies add their Newton loop and dense
boundary blocks (compute.deformable).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from compute import detection, walls
from compute.compliance import Compliance, delassus_blocks
from compute.contact_geometry import Contacts
from compute.errors import SimulationError
from compute.model import Model
from compute.nlgs import apply_impulses, nlgs_solve
from compute.state import State


@dataclass
class StepReport:
    sweeps: int
    residual: float
    n_contacts: int  # contacts carrying a positive normal impulse
    max_penetration: float  # max(-gap) at the start of the step, >= 0
    contacts: Contacts


class Stepper:
    """Advances a :class:`State` of a :class:`Model` by one step under a wall load."""

    def __init__(self, model: Model):
        self.model = model
        s = model.scene.solver
        self.h, self.theta = s.time_step, s.theta
        self.f_gravity = model.gravity_forces()
        lay = model.layout
        self.rigid_dofs = np.arange(3 * lay.n_rigid)
        inv = np.column_stack([1 / model.mass, 1 / model.mass, 1 / model.inertia])
        inv[model.fixed] = 0.0  # fixed bodies: zero compliance, their velocity stays 0
        self.rigid_inverse_mass = inv.ravel()
        self.wall_dofs = lay.wall_dof0 + np.arange(4)

    def step(self, state: State, pressure: float, wall_speed: float = 0.0) -> StepReport:
        """Advance ``state`` in place. Pressure control if ``self.model.scene.walls.control`` is
        "pressure" (walls pushed by ``pressure`` × length), else walls move inward at ``wall_speed``."""
        contacts = self.contacts(state)
        v_free, diag_dofs, diag = self.free_velocity(state, pressure, wall_speed)
        comp = Compliance.build(self.model.layout.n_dofs, diag_dofs, diag)
        v, sweeps, residual = self.solve_contacts(state, contacts, v_free, comp)
        return self.finish(state, v, contacts, sweeps, residual)

    # --- the pieces of a step, reused by the deformable stepper ---------------------------
    def contacts(self, state: State) -> Contacts:
        """Candidate contacts at q_n (re-detected when something moved past half the skin)."""
        if detection.needs_detection(self.model, state):
            detection.detect(self.model, state)
        return detection.narrow_phase(self.model, state)

    def free_velocity(self, state: State, pressure: float, wall_speed: float):
        """Free velocity (n_dofs,) of rigid disks and walls, and their diagonal compliance
        (dofs (k,), 1 / m̂ (k,))."""
        h = self.h
        v_free = state.v.copy()
        v_free[self.rigid_dofs] += h * self.rigid_inverse_mass * self.f_gravity[self.rigid_dofs]
        wall_inv = self._free_wall_velocity(state, v_free, pressure, wall_speed)
        return (v_free, np.concatenate([self.rigid_dofs, self.wall_dofs]),
                np.concatenate([self.rigid_inverse_mass, wall_inv]))

    def solve_contacts(self, state: State, contacts: Contacts, v_free: np.ndarray, comp: Compliance):
        """NLGS from the warm-start impulses in ``contacts``; returns (v⁺, sweeps, residual)."""
        h, th, s = self.h, self.theta, self.model.scene.solver
        carr = comp.arrays()
        un_minus = np.sum(contacts.hn * state.v[contacts.dof], axis=1)
        gap_term = (contacts.gap + h * (1.0 - th) * un_minus) / (h * th)
        W = np.empty((len(contacts), 2, 2))
        delassus_blocks(contacts.dof, contacts.hn, contacts.ht, *carr, W)
        v = v_free.copy()
        apply_impulses(contacts.dof, contacts.hn, contacts.ht, contacts.impulse, v, *carr)
        sweeps, residual = nlgs_solve(contacts.dof, contacts.hn, contacts.ht, W, gap_term, contacts.mu,
                                      contacts.impulse, v, *carr, s.nlgs_tolerance, s.nlgs_max_sweeps,
                                      s.relaxation)
        if not np.all(np.isfinite(v)):
            raise SimulationError(f"step {state.step}: non-finite velocities after the contact solve "
                                  f"(NLGS residual {residual:.3g} after {sweeps} sweeps)")
        return v, sweeps, residual

    def finish(self, state: State, v: np.ndarray, contacts: Contacts, sweeps: int, residual: float) -> StepReport:
        """θ-update of positions, time and contact memory."""
        h, th = self.h, self.theta
        state.q += h * ((1.0 - th) * state.v + th * v)
        state.v = v
        state.time += h
        state.step += 1
        detection.store_impulses(state, contacts)
        return StepReport(sweeps, residual, int(np.count_nonzero(contacts.impulse[:, 0] > 0.0)),
                          float(max(0.0, -contacts.gap.min())) if len(contacts) else 0.0, contacts)

    def _free_wall_velocity(self, state: State, v_free: np.ndarray, pressure: float,
                            wall_speed: float) -> np.ndarray:
        """Set the walls' free velocity in ``v_free``; return their compliance 1 / m̂ (4,)."""
        m, h, th = self.model, self.h, self.theta
        wd = self.wall_dofs
        if m.scene.walls.control == "velocity":
            v_free[wd] = walls.INWARD * wall_speed
            return np.zeros(4)
        bounds = m.bounds(state.q)
        force = walls.pressure_forces(bounds, pressure)
        c = walls.damping_coefficients(bounds, pressure, m.scene.walls.damping_inertial_number,
                                       m.density, m.diameter)
        m_hat = m.wall_mass + th * h * c
        v_free[wd] = state.v[wd] + h * (force - c * state.v[wd]) / m_hat
        return 1.0 / m_hat
