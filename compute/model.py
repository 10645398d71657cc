"""The mechanical model of a scene: a list of body groups, their dof layout, the contact
families between their kinds, and the measures of a configuration (box, packing fraction).

Dofs (q, v) are laid out group after group: rigid disks (x, y, rotation), the four walls, then
the soft groups' nodes (x, y); all soft nodes of the model are numbered globally in that order
(node g has the dofs ``node_dof0 + 2 g + (0, 1)``), which the soft contact rows use.
"""

from __future__ import annotations

import numpy as np

from compute.bodies.rigid import RigidDisks
from compute.bodies.soft import SoftBodies
from compute.bodies.walls import Walls
from compute.contact.families import families_of
from compute.fem import NeoHookean
from compute.state import State


class Model:
    """Groups built from a validated :class:`compute.scene.Scene`.

    ``rigid`` (RigidDisks, possibly empty), ``walls`` (Walls), ``soft`` (list of SoftBodies, one
    per reference mesh and material); ``groups`` all of them in dof order; ``families`` the
    contact families present; ``friction`` (n_mat, n_mat); ``moving_rigid`` the number of rigid
    disks that are not fixed. Soft-node arrays for the contact
    kernels: ``loop_nodes`` (n_b,) boundary loops (global node ids, CCW, body after body) with
    offsets ``loop_start`` (nd + 1,), ``loop_neighbours`` (N, 2) the previous and next node of
    each node in its loop (-1 for interior nodes), ``node_body`` (N,) soft index of each node, ``soft_ids``
    (nd,) and ``soft_material`` (nd,) of each soft index.
    """

    def __init__(self, scene):
        self.scene = scene
        mats = [scene.materials[n] for n in scene.material_names]
        rid = scene.rigid_ids
        rmat = scene.body_material[rid]
        self.rigid = RigidDisks(rid, scene.rigid_centres, scene.rigid_radii,
                                [mats[m].density for m in rmat], [mats[m].fixed for m in rmat], rmat)
        self.diameter = scene.mean_diameter
        self.density = float(np.mean([m.density for m in scene.materials.values()]))
        w = scene.walls
        self.walls = Walls(w.bounds, w.mass, w.control, w.damping_inertial_number, self.density, self.diameter,
                           dof0=self.rigid.dofs.stop)
        self.soft = self._soft_groups(scene, self.walls.dofs.stop)
        self.groups = [self.rigid, self.walls, *self.soft]
        self.n_dofs = self.groups[-1].dofs.stop
        self.friction = scene.friction
        self.moving_rigid = int(np.count_nonzero(~self.rigid.fixed))
        self.skin = scene.solver.skin
        kinds = {g.kind for g in self.groups if len(g)}
        self.families = families_of(kinds, scene.solver.rigid_soft_rows)
        self.node_dof0 = self.walls.dofs.stop
        self.soft_ids = np.concatenate([np.zeros(0, np.int64)] + [g.ids for g in self.soft])
        self.soft_material = np.concatenate([np.zeros(0, np.int64)] + [np.full(g.B, g.material) for g in self.soft])
        counts = np.concatenate([np.zeros(0, np.int64)] + [np.full(g.B, g.n_nodes) for g in self.soft])
        self.node_body = np.repeat(np.arange(len(counts)), counts).astype(np.int64)
        self.loop_nodes = np.concatenate([np.zeros(0, np.int64)] + [g.loop_nodes for g in self.soft]).astype(np.int64)
        sizes = np.concatenate([np.zeros(0, np.int64)] + [np.diff(g.loop_start) for g in self.soft])
        self.loop_start = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
        self.loop_neighbours = loop_neighbours(self.loop_nodes, self.loop_start, len(self.node_body))

    @staticmethod
    def _soft_groups(scene, dof0: int) -> list[SoftBodies]:
        """One group per (material, connectivity) of the scene's deformable bodies."""
        from compute.errors import SceneError

        groups: dict = {}
        for d in scene.deformable:
            key = (int(scene.body_material[d.body]), d.element, d.cells.shape, d.cells.tobytes())
            groups.setdefault(key, []).append(d)
        out, node0 = [], 0
        for (m, element, _, _), bodies in groups.items():
            mat = scene.materials[scene.material_names[m]]
            try:
                g = SoftBodies([d.body for d in bodies], np.stack([d.points for d in bodies]), bodies[0].cells, element,
                               NeoHookean(mat.young, mat.poisson, mat.density), mat.volumetric, m, dof0, node0,
                               scene.solver.hold_rotation)
            except ValueError as exc:
                raise SceneError(scene.path / "bodies.vtu", f"cells of the bodies {[d.body for d in bodies][:10]}",
                                 "valid counter-clockwise disk meshes", str(exc)) from None
            out.append(g)
            dof0, node0 = g.dofs.stop, node0 + g.B * g.n_nodes
        return out

    # --- state -------------------------------------------------------------------------------
    def initial_state(self) -> State:
        q = np.zeros(self.n_dofs)
        for g in self.groups:
            g.initial(q)
        return State(q=q, v=np.zeros(self.n_dofs))

    @property
    def nonlinear(self) -> bool:
        """True when some group needs Newton iterations within a step."""
        return any(g.nonlinear and len(g) for g in self.groups)

    def soft_nodes(self, a: np.ndarray) -> np.ndarray:
        """(N, 2) view of all soft node positions (or velocities) of q (or v)."""
        return a[self.node_dof0:].reshape(-1, 2)

    def soft_circles(self, q) -> tuple[np.ndarray, np.ndarray]:
        """Bounding circles of the soft boundary loops: centres (nd, 2), radii (nd,)."""
        parts = [g.bounding_circles(q) for g in self.soft]
        return (np.concatenate([np.zeros((0, 2))] + [c for c, _ in parts]),
                np.concatenate([np.zeros(0)] + [r for _, r in parts]))

    def tracked_points(self, q) -> np.ndarray:
        """Points (k, 2) whose motion invalidates the Verlet lists: rigid centres, soft boundary nodes."""
        return np.vstack([self.rigid.centres(q), self.soft_nodes(q)[self.loop_nodes]])

    # --- measures -----------------------------------------------------------------------------
    def bounds(self, q: np.ndarray) -> np.ndarray:
        """Box (xmin, xmax, ymin, ymax) from the wall dofs."""
        return self.walls.bounds(q)

    def wall_velocity(self, v: np.ndarray) -> np.ndarray:
        return self.walls.bounds(v)

    def centres(self, q: np.ndarray) -> np.ndarray:
        """Centres (n_bodies, 2) of all bodies in the global body numbering (soft: centroids)."""
        c = np.zeros((self.scene.n_bodies, 2))
        c[self.rigid.ids] = self.rigid.centres(q)
        for g in self.soft:
            c[g.ids] = g.centres(q)
        return c

    def particle_area(self, q: np.ndarray) -> float:
        return self.rigid.area(q) + sum(g.area(q) for g in self.soft)

    def particle_mass(self) -> float:
        """Mass of the particles: rigid disks', and soft bodies' reference mass times their
        stage's mass scale (the inertia a stage moves)."""
        soft = sum(g.batch.material.density * g.batch.reference_areas.sum() * g.batch.mass_scale for g in self.soft)
        return float(self.rigid.mass.sum() + soft)

    def phi(self, q: np.ndarray) -> float:
        """Packing fraction φ = V_p / V with current particle areas."""
        b = self.bounds(q)
        return self.particle_area(q) / ((b[1] - b[0]) * (b[3] - b[2]))

    def kinetic_energy(self, v: np.ndarray) -> float:
        return float(sum(g.kinetic_energy(v) for g in self.groups))

    def frame_contacts(self, state: State):
        """All contacts at the state's configuration with the impulses of its memory (a frame's)."""
        from compute.contact import detection

        return detection.narrow_phase(self, state)

    def meshes(self, q: np.ndarray) -> dict:
        """{soft body id: (points (n, 2), cells, element)} in the current configuration."""
        out = {}
        for g in self.soft:
            out.update(g.meshes(q))
        return out

    def frame_fields(self, state: State) -> dict:
        """Point and cell fields of the bodies frame (layout of compute.bodies_io.write_bodies)."""
        point, cell = {}, {}
        rp, rc = self.rigid.frame_fields(state.q, state.v)
        for fields, rigid in ((point, rp), (cell, rc)):
            for name, value in rigid.items():
                fields[name] = {"rigid": value, "deformable": {}}
        for g in self.soft:
            sp, sc = g.frame_fields(state.q, state.v)
            for fields, soft in ((point, sp), (cell, sc)):
                for name, value in soft.items():
                    fields[name]["deformable"].update(zip(g.ids.tolist(), value))
        return {"point": point, "cell": cell}


def loop_neighbours(loop_nodes: np.ndarray, loop_start: np.ndarray, n_nodes: int) -> np.ndarray:
    """(n_nodes, 2): the previous and next node of each node of the loops ``loop_nodes`` (offsets
    ``loop_start``), -1 for nodes in no loop."""
    i = np.arange(len(loop_nodes))
    loop = np.repeat(np.arange(len(loop_start) - 1), np.diff(loop_start))
    first, last = loop_start[loop], loop_start[loop + 1] - 1
    out = np.full((n_nodes, 2), -1, np.int64)
    out[loop_nodes, 0] = loop_nodes[np.where(i == first, last, i - 1)]
    out[loop_nodes, 1] = loop_nodes[np.where(i == last, first, i + 1)]
    return out
