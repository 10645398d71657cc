"""The mechanical model built from a scene: dof layout, masses, radii, friction, and measures of
a configuration (box, packing fraction)."""

from __future__ import annotations

import numpy as np

from compute.scene import Scene
from compute.state import Layout, State


class Model:
    """Rigid disks and four walls (deformable bodies are added by :mod:`compute.deformable`).

    Arrays: ``radii`` (nr,), ``mass`` (nr,), ``inertia`` (nr,), ``rigid_material`` (nr,)
    indices into ``friction`` (n_mat, n_mat); ``wall_mass`` scalar.
    """

    def __init__(self, scene: Scene):
        self.scene = scene
        ids = scene.rigid_ids
        order = np.argsort(ids)
        self.rigid_ids = ids[order]
        self.radii = scene.rigid_radii[order]
        self.rigid_material = scene.body_material[self.rigid_ids]
        rho = np.array([scene.materials[scene.material_names[m]].density for m in self.rigid_material])
        self.mass = rho * np.pi * self.radii**2
        self.inertia = 0.5 * self.mass * self.radii**2
        self.fixed = np.array([scene.materials[scene.material_names[m]].fixed for m in self.rigid_material], bool)
        self.friction = scene.friction
        self.wall_mass = scene.walls.mass
        self.layout = Layout(n_rigid=len(self.rigid_ids))
        self._initial_centres = scene.rigid_centres[order]
        self.diameter = scene.mean_diameter
        densities = [m.density for m in scene.materials.values()]
        self.density = float(np.mean(densities))

    def make_stepper(self):
        """The time stepper for this model."""
        from compute.stepper import Stepper

        return Stepper(self)

    # --- state -------------------------------------------------------------------------
    def initial_state(self) -> State:
        n = self.layout.n_dofs
        q = np.zeros(n)
        r = self.rigid_view(q)
        r[:, :2] = self._initial_centres
        q[self.layout.wall_dof0:self.layout.wall_dof0 + 4] = self.scene.walls.bounds
        return State(q=q, v=np.zeros(n))

    def rigid_view(self, a: np.ndarray) -> np.ndarray:
        """(nr, 3) view (x, y, rotation) of the rigid part of q or v."""
        return a[: 3 * self.layout.n_rigid].reshape(-1, 3)

    def bounds(self, q: np.ndarray) -> np.ndarray:
        """Box (xmin, xmax, ymin, ymax) from the wall dofs."""
        w = self.layout.wall_dof0
        return q[w:w + 4]

    def wall_velocity(self, v: np.ndarray) -> np.ndarray:
        w = self.layout.wall_dof0
        return v[w:w + 4]

    def body_centres(self, q: np.ndarray) -> np.ndarray:
        """Centres (n_bodies, 2) of all bodies in the global body numbering."""
        c = np.zeros((self.scene.n_bodies, 2))
        c[self.rigid_ids] = self.rigid_view(q)[:, :2]
        return c

    def frame_contacts(self, state: State):
        """All contacts at the state's configuration with the impulses of its memory (a frame's)."""
        from compute import detection

        return detection.narrow_phase(self, state)

    def current_meshes(self, q: np.ndarray) -> dict:
        """Deformable meshes in the current configuration (none for a rigid model)."""
        return {}

    def frame_fields(self, state: State) -> dict:
        """Point and cell fields of the bodies frame (layout of compute.bodies_io.write_bodies)."""
        r, v = self.rigid_view(state.q), self.rigid_view(state.v)
        z = np.zeros((len(r), 1))
        zero = np.zeros(len(r))
        point = {"displacement": {"rigid": np.hstack([r[:, :2] - self._initial_centres, z])},
                 "velocity": {"rigid": np.hstack([v[:, :2], z])}}
        cell = {"rotation": {"rigid": r[:, 2]}, "angular_velocity": {"rigid": v[:, 2]},
                "cauchy_stress": {"rigid": np.zeros((len(r), 9))}, "pressure": {"rigid": zero},
                "von_mises": {"rigid": zero}}
        return {"point": point, "cell": cell}

    def particle_area(self, q: np.ndarray) -> float:
        return float(np.pi * np.sum(self.radii**2))

    def phi(self, q: np.ndarray) -> float:
        """Packing fraction φ = V_p / V with current particle areas."""
        b = self.bounds(q)
        return self.particle_area(q) / ((b[1] - b[0]) * (b[3] - b[2]))

    def kinetic_energy(self, v: np.ndarray) -> float:
        rv = self.rigid_view(v)
        wv = self.wall_velocity(v)
        return float(0.5 * (np.sum(self.mass * np.sum(rv[:, :2] ** 2, axis=1)) + np.sum(self.inertia * rv[:, 2] ** 2)
                            + self.wall_mass * np.sum(wv**2)))

    def gravity_forces(self) -> np.ndarray:
        """External generalised forces (n_dofs,) of gravity."""
        f = np.zeros(self.layout.n_dofs)
        g = self.scene.loading.gravity
        r = self.rigid_view(f)
        r[:, 0] = np.where(self.fixed, 0.0, self.mass * g[0])
        r[:, 1] = np.where(self.fixed, 0.0, self.mass * g[1])
        return f
