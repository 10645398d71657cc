"""Scenes with deformable disks for the tests: written by pre.scene, run by compute's stepper."""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
E, NU, RHO = 1.0, 0.495, 1.0


def disk(n: int = 92, element: str = "T6", centre=(0.0, 0.0), radius: float = 1.0, turn: float = 0.0):
    """(points (m, 2), cells) of a gmsh disk mesh, a boundary segment centred on the +x axis
    (then turned by ``turn`` radians), scaled and placed."""
    from pre.mesh import reference_disk_mesh
    from pre.single_particle import face_on

    mesh = reference_disk_mesh(n, element)
    p = face_on(mesh.points, mesh.boundary_nodes)
    c, s = np.cos(turn), np.sin(turn)
    p = p @ np.array([[c, -s], [s, c]]).T
    return p * radius + np.asarray(centre, float), np.array(mesh.cells)


def parameters(bounds, *, element: str = "T6", friction: float = 0.0, time_step: float = 1.0, theta: float = 1.0,
               wall_mass: float = np.pi, control: str = "pressure", pressures=(1e-3,), gravity=(0.0, 0.0),
               newton_tolerance: float = 1e-9, contact_tolerance: float = 1e-10, check_every: int = 2,
               phi_tolerance: float = 1e-6, max_steps: int = 400, young: float = E, poisson: float = NU) -> dict:
    from pre.scene import contact_laws, neo_hookean_material, rigid_material, scene_parameters

    return scene_parameters(
        {"soft": neo_hookean_material(element, young=young, poisson=poisson, density=RHO),
         "rigid": rigid_material(RHO)}, contact_laws(["soft", "rigid"], friction),
        **dict(zip(("xmin", "xmax", "ymin", "ymax"), bounds)), mass=wall_mass, control=control,
        pressures=list(pressures), velocity=0.0, duration=1.0, phi_tolerance=phi_tolerance,
        inertial_tolerance=1e-4, check_every=check_every, max_steps_per_stage=max_steps, gravity=list(gravity),
        time_step=time_step, theta=theta, contact_tolerance=contact_tolerance, nlgs_max_sweeps=50000, relaxation=1.0,
        skin=0.05, newton_tolerance=newton_tolerance, newton_max_iterations=40,
        frames="stages", every_steps=0, checkpoint_every_steps=100000)


def write(folder, params: dict, soft=(), rigid=()) -> Path:
    """Scene with deformable disks ``soft`` = [(points, cells)] and rigid disks ``rigid`` =
    [(centre, radius)]; bodies numbered soft first."""
    from pre.scene import write_scene

    params = copy.deepcopy(params)
    element = params["materials"]["soft"]["element"]
    n = len(soft) + len(rigid)
    centres, radii, mats, meshes = np.zeros((n, 2)), np.zeros(n), [], {}
    for k, (p, cells) in enumerate(soft):
        centres[k] = 0.5 * (p.min(axis=0) + p.max(axis=0))
        radii[k] = 0.5 * (p.max(axis=0) - p.min(axis=0)).max()
        mats.append("soft")
        meshes[k] = (p, cells, element)
    for j, (c, r) in enumerate(rigid, start=len(soft)):
        centres[j], radii[j] = c, r
        mats.append("rigid")
    return write_scene(folder, params, centres, radii, mats, meshes=meshes)


def pressed_three(folder, friction: float, time_step: float, newton_tolerance: float = 1e-9,
                  contact_tolerance: float = 1e-3, pressure: float = 0.05):
    """(model, stepper, state) of three soft T3 x 30 disks of radius 1 in a box just larger than
    them, pressed together by the walls at ``pressure`` (P/E)."""
    soft = [disk(30, "T3", centre=c, radius=1.0) for c in ((0.0, 0.0), (2.0, 0.0), (1.0, 1.73))]
    params = parameters((-1.02, 3.02, -1.02, 2.75), element="T3", friction=friction, time_step=time_step,
                        newton_tolerance=newton_tolerance, contact_tolerance=contact_tolerance, pressures=(pressure,))
    write(folder, params, soft=soft)
    return load(folder)


def load(folder):
    """(model, stepper, state) of a scene folder."""
    from compute.model import Model
    from compute.scene import read_scene
    from compute.stepping.moreau_jean import Stepper

    model = Model(read_scene(folder))
    return model, Stepper(model), model.initial_state()


def fe_body(model, k: int = 0):
    """An FEBody (the per-body reference implementation) of soft body k of the first soft group,
    in its reference configuration."""
    from compute.fem import FEBody

    g = model.soft[0]
    b = g.batch
    return FEBody(b.X[k], b.cells, b.element.name, b.material, b.volumetric)


def body_nodes(model, a, k: int = 0):
    """(n, 2) view of soft body k's nodes (first soft group) in q or v."""
    return model.soft[0].nodes(a)[k]


def pin_walls(stepper, walls=(0, 1)) -> None:
    """Hold the given walls still (zero velocity, zero compliance) whatever the wall control."""
    stepper.model.walls.held[list(walls)] = True


def wall_forces(model, state, h: float) -> np.ndarray:
    """Normal force (4,) of the particles on each wall, from the contact memory."""
    from compute.frames import wall_forces as wf

    return wf(model.frame_contacts(state), h)


def settle(stepper, state, pressure: float, steps: int, tol: float = 0.0, wall_speed: float = 0.0):
    """Step until the positions change by less than tol (relative to 1) over a step, or ``steps``."""
    for _ in range(steps):
        q0 = state.q.copy()
        state, _ = stepper.step(state, pressure, wall_speed)
        if tol and np.abs(state.q - q0).max() < tol:
            break
    return state
