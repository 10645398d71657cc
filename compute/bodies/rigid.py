"""Rigid disks: dofs (x, y, rotation) per disk, a diagonal mass, a linear free flight.

Free velocity over a step (Moreau–Jean, θ-scheme, gravity the only external force):
v_free = v⁻ + h M⁻¹ m g. Fixed disks have zero compliance and stay at rest.
"""

from __future__ import annotations

import numpy as np

from compute.bodies.step_records import LinearStep


class RigidDisks:
    """``ids`` (nr,) global body ids in increasing order; ``radii``, ``mass``, ``inertia``,
    ``material`` (nr,); ``fixed`` (nr,) bool; ``dof0`` first dof: disk k has dofs
    dof0 + 3k + (0, 1, 2)."""

    kind = "rigid"
    nonlinear = False

    def __init__(self, ids, centres, radii, density, fixed, material, dof0: int = 0):
        order = np.argsort(ids)
        self.ids = np.asarray(ids, np.int64)[order]
        self.radii = np.asarray(radii, float)[order]
        self.material = np.asarray(material, np.int64)[order]
        self.fixed = np.asarray(fixed, bool)[order]
        self.mass = np.asarray(density, float)[order] * np.pi * self.radii**2
        self.inertia = 0.5 * self.mass * self.radii**2
        self.initial_centres = np.asarray(centres, float)[order]
        self.dof0 = dof0
        self.dofs = slice(dof0, dof0 + 3 * len(self.ids))
        inverse = np.column_stack([1 / self.mass, 1 / self.mass, 1 / self.inertia])
        inverse[self.fixed] = 0.0  # fixed bodies: zero compliance, their velocity stays 0
        self.inverse_mass = inverse.ravel()

    def __len__(self) -> int:
        return len(self.ids)

    def view(self, a: np.ndarray) -> np.ndarray:
        """(nr, 3) view (x, y, rotation) of this group's part of q or v."""
        return a[self.dofs].reshape(-1, 3)

    def dof_of(self) -> np.ndarray:
        """First dof (nr,) of every disk."""
        return self.dof0 + 3 * np.arange(len(self.ids), dtype=np.int64)

    def initial(self, q: np.ndarray) -> None:
        self.view(q)[:, :2] = self.initial_centres

    # --- the step -----------------------------------------------------------------------
    def begin_step(self, q, v, h, theta, load) -> LinearStep:
        g = np.where(self.fixed[:, None], 0.0, np.asarray(load.gravity, float))
        dv = np.zeros((len(self.ids), 3))
        dv[:, :2] = h * g  # h M⁻¹ (m g)
        return LinearStep(np.arange(self.dofs.start, self.dofs.stop), v[self.dofs] + dv.ravel(), self.inverse_mass)

    # --- measures -----------------------------------------------------------------------
    def centres(self, q) -> np.ndarray:
        return self.view(q)[:, :2]

    def area(self, q) -> float:
        return float(np.pi * np.sum(self.radii**2))

    def kinetic_energy(self, v) -> float:
        rv = self.view(v)
        return float(0.5 * (np.sum(self.mass * np.sum(rv[:, :2] ** 2, axis=1)) + np.sum(self.inertia * rv[:, 2] ** 2)))

    def frame_fields(self, q, v) -> tuple[dict, dict]:
        """Point and cell fields over the disks (one point and one vertex cell each)."""
        r, w = self.view(q), self.view(v)
        z = np.zeros((len(r), 1))
        zero = np.zeros(len(r))
        point = {"displacement": np.hstack([r[:, :2] - self.initial_centres, z]), "velocity": np.hstack([w[:, :2], z])}
        cell = {"rotation": r[:, 2].copy(), "angular_velocity": w[:, 2].copy(), "cauchy_stress": np.zeros((len(r), 9)),
                "pressure": zero, "von_mises": zero}
        return point, cell
