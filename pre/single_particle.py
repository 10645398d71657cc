"""The single-particle scene: one neo-Hookean disk in a box of four pressure-driven walls.

A disk of radius R = 1 (E = 1, ν = 0.495, density 1, plane strain by default), meshed by gmsh
(:func:`pre.mesh.reference_disk_mesh`), turned face-on to the walls, in a box of four
frictionless walls touching it; pressure stages P/E log-spaced. Reduced units: R = 1, E = 1,
density 1.

Quasi-static settings (measured, studies/single_particle/README.md): θ = 1 (backward Euler: a
step tends to an implicit static step with contact), h = 10, walls of the disk's mass, no wall
damping; a stage is equilibrated when φ changes by less than 1e-5 (relative) over
``check_every`` = 2 steps and the walls' inertial number is below 1e-4. The disk's rigid
rotation is held (``solver.hold_rotation``): nothing else holds it between frictionless walls,
and the compressive loads make it unstable; free, the disk rolls one way or the other
depending on h, and φ with it (studies/single_particle/README.md).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

# The default soft disk: T6, standard volumetric term, a target of 100 triangles (101: 21
# boundary segments). Measured against the converged refinement (studies/single_particle/README.md,
# "The best T6 disk near 92 elements"): several times closer in phi_p at every stage up to
# P/E = 0.4 than the paper's 92 triangles (20 segments): with a number of segments divisible
# by 4 each wall presses a face and boundary nodes join the contact in symmetric pairs, so the curve
# climbs in larger stairs.
ELEMENTS = 100


def parameters(pressures, *, element: str, volumetric: str, time_step: float, theta: float, wall_mass: float,
               phi_tolerance: float, check_every: int, newton_tolerance: float, contact_tolerance: float,
               bounds, poisson: float = 0.495, max_steps: int = 2000, hold_rotation: bool = True) -> dict:
    """The scene parameters of the single-particle study (reduced units)."""
    from pre.scene import contact_laws, neo_hookean_material, scene_parameters

    return scene_parameters(
        {"soft": neo_hookean_material(element, volumetric, poisson=poisson)}, contact_laws(["soft"], 0.0),
        **dict(zip(("xmin", "xmax", "ymin", "ymax"), bounds)), mass=wall_mass, control="pressure",
        pressures=[float(p) for p in pressures], phi_tolerance=phi_tolerance, inertial_tolerance=1e-4,
        check_every=check_every, max_steps_per_stage=max_steps, gravity=[0.0, 0.0],
        time_step=time_step, theta=theta, contact_tolerance=contact_tolerance, nlgs_max_sweeps=20000, relaxation=1.0,
        skin=0.05, newton_tolerance=newton_tolerance, newton_max_iterations=40, hold_rotation=hold_rotation,
        frames="stages", every_steps=0, checkpoint_every_steps=1000)


def face_on(points: np.ndarray, loop: np.ndarray) -> np.ndarray:
    """The unit-disk mesh points (n, 2) rotated so that a boundary segment (between consecutive
    nodes of the CCW ``loop``) is centred on the +x axis.

    The boundary is a polygon (T3: the element edges; T6: the half-edges between corner and
    midside nodes, the straight segments the contacts see). A polygon pressed by a flat wall
    is stable on a face and unstable on a vertex: with a vertex against the walls the disk
    rotates by half a segment during the first stages (seen with 20 segments: 9 degrees, while
    phi wanders by 1e-3). With a number of segments divisible by 4 every wall then faces a
    segment; otherwise the walls other than +x face nearly a segment."""
    a = points[loop]
    b = np.roll(a, -1, axis=0)
    mid = np.arctan2(*(0.5 * (a + b))[:, ::-1].T)
    t = -mid[np.argmin(np.abs(mid))]
    rot = np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]])
    return points @ rot.T


def write(folder, *, element: str = "T6", elements: int = ELEMENTS, boundary_segments: int | None = None,
          volumetric: str = "standard",
          p_min: float = 1e-3, p_max: float = 1.0, stages: int = 16, time_step: float = 10.0,
          theta: float = 1.0, wall_mass: float | None = None, phi_tolerance: float = 1e-5,
          check_every: int = 2, newton_tolerance: float = 1e-7, contact_tolerance: float = 1e-8,
          pressures=None, hold_rotation: bool = True) -> Path:
    """Write the scene folder; returns its path. ``pressures`` overrides the log-spaced stages;
    ``boundary_segments`` grades the mesh toward the boundary (pre.mesh.reference_disk_mesh);
    ``hold_rotation`` False lets the disk roll (module docstring)."""
    from pre.mesh import reference_disk_mesh
    from pre.scene import write_scene

    mesh = reference_disk_mesh(elements, element, boundary_segments)
    p = face_on(mesh.points, mesh.boundary_nodes)
    bounds = (float(p[:, 0].min()), float(p[:, 0].max()), float(p[:, 1].min()), float(p[:, 1].max()))
    if pressures is None:
        pressures = np.geomspace(p_min, p_max, stages)
    params = parameters(pressures, element=element, volumetric=volumetric, time_step=time_step, theta=theta,
                        wall_mass=np.pi if wall_mass is None else wall_mass, phi_tolerance=phi_tolerance,
                        check_every=check_every, newton_tolerance=newton_tolerance,
                        contact_tolerance=contact_tolerance, bounds=bounds, hold_rotation=hold_rotation)
    return write_scene(folder, params, np.zeros((1, 2)), np.ones(1), ["soft"],
                       meshes={0: (p, np.array(mesh.cells), element)})
