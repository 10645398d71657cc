"""Rigid/soft mixtures: a fraction κ of the particle volume of a jammed rigid packing replaced by
deformable (neo-Hookean, finite-element) disks at the same positions and with the same sizes.

The paper (Cárdenas-Barrantes et al. 2021, Sec. 2): "a volume κ V_p is homogeneously replaced by
deformable disks meshed with 92 triangular similar-size elements". Here "homogeneously" means a
random choice that is spatially uniform: the disks are taken in the order of a random permutation
(independent of position, so every region of the box is equally likely to receive soft disks), and
the chosen set is the prefix of that order whose area is closest to κ V_p, refined by one swap
(the last chosen disk against an unchosen one) when that brings the area closer. The area error
is then at most half the area difference between two disks, well below one disk's area.

Public API
----------
- :func:`choose_deformable`: the mask (n,) of disks to make deformable, for radii (n,) and κ.
- :func:`mixture_scene`: read a rigid scene folder, write the mixture scene folder.
- :func:`compaction_parameters`: the scene tables of a quasi-static isotropic compaction in
  P/E stages (reduced units ⟨d⟩ = ρ = E = 1), :data:`QUASI_STATIC` its numerical settings.

pre reads the rigid scene from its files (compute.scene.read_scene validates it), never from
another stage's memory.
"""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np

__all__ = ["choose_deformable", "mixture_scene", "compaction_parameters", "QUASI_STATIC",
           "frictional_tolerance", "frictionless_screening", "rigid_soft_rows",
           "RIGID", "SOFT"]

RIGID, SOFT = "rigid", "soft"

# Numerical settings of the quasi-static compaction, "table.key" -> value, in reduced units
# (<d> = 1, rho = 1, E = 1; time unit <d> sqrt(rho/E)). theta = 1 makes a step nearly an implicit
# static step. h and the Newton tolerance (on the position correction, in <d>): on a
# high-pressure stage of 30 soft disks, h = 0.5 with 1e-5 is the cheapest setting tried that
# cuts almost no step, and it moves the equilibrated phi by less than the stage's own tolerance
# (1e-4) from 1e-6; a larger h or a tighter tolerance costs more cuts and time
# (benchmarks/results/mixture_settings.md). Wall damping with terminal inertial number 1e-2
# moves the walls toward the next equilibrium much sooner than 1e-3, and a wall force balance
# of 1e-2 avoids the slow creep of the box shape that kept a 1e-3 balance unmet (40-disk
# mixtures, benchmarks/results/design_figures.md); a stage still ends only when I < 1e-4.
# That damping does not grow with the box, and a large packing rings after each pressure step
# for hundreds of steps: the walls are also damped at the critical damping of the packing's
# breathing mode (damping ratio 1, compute.bodies.walls), which ends those stages in about half
# the steps and nearer the slow-loading limit of φ (benchmarks/results/wall_damping.md).
QUASI_STATIC = {
    "solver.time_step": 0.5, "solver.theta": 1.0, "solver.contact_tolerance": 1e-4, "solver.nlgs_max_sweeps": 2000,
    "solver.newton_tolerance": 1e-5, "solver.newton_max_iterations": 25,
    "walls.damping_inertial_number": 1e-2, "walls.damping_ratio": 1.0,
    "loading.phi_tolerance": 1e-4, "loading.inertial_tolerance": 1e-4, "loading.force_tolerance": 1e-2,
    "loading.check_every": 20, "loading.max_steps_per_stage": 5000,
    "output.checkpoint_every_steps": 200,
}


def compaction_parameters(bounds: tuple[float, float, float, float], friction: float, pressures,
                          overrides: dict | None = None, element: str = "T3", bodies: int = 0) -> dict:
    """Walls, loading, solver and output tables (pre.scene.default_parameters layout) of an
    isotropic compaction by frictionless pressure-driven walls, no gravity, through the stages
    ``pressures`` (P/E, E = 1), each run to equilibrium (phi variation < 1e-4 over check_every
    steps, inertial number < 1e-4, wall force = P L within 1 %). :data:`QUASI_STATIC`, the
    contact tolerance (:func:`frictional_tolerance`), the screening of a packing of ``bodies``
    bodies (:func:`frictionless_screening`) and the rows the soft disks' ``element`` needs
    (:func:`rigid_soft_rows`), then ``overrides`` ("table.key" -> value) set the
    numerical settings."""
    from pre.scene import default_parameters, overridden

    params = default_parameters(bounds, friction, 1.0, [float(p) for p in pressures])
    return overridden(params, {**QUASI_STATIC, **frictional_tolerance(friction), **frictionless_screening(friction, bodies),
                               **rigid_soft_rows(element), **(overrides or {})})


def frictional_tolerance(friction: float) -> dict:
    """Contact tolerance of a compaction at ``friction`` > 0: 1e-3 instead of
    :data:`QUASI_STATIC`'s 1e-4.

    Frictional contacts are solved by Gauss-Seidel (NLGS, then block Gauss-Seidel where it
    stalls), whose sweeps are most of a large packing's step and whose last decade of error
    costs most of them. On the 1500-disk mixtures at every κ, μ = 0.2, the looser tolerance
    completes every run at a fraction of the sweeps and moves each stage's φ by less than the
    run's other numerical errors, its time step, stage test and mesh
    (benchmarks/results/cost_error_n1500_k*_mu0.2.md, numerical_error_n1500_k0.2_mu0.2.md).
    Frictionless runs keep 1e-4: their projected-gradient solver (MPRGP) reaches it in few
    iterations."""
    return {"solver.contact_tolerance": 1e-3} if friction > 0.0 else {}


def frictionless_screening(friction: float, bodies: int) -> dict:
    """Contact screening of a compaction of ``bodies`` bodies at ``friction``: each contact solve
    on the contacts that can close (solver.contact_screening 0.1, compute.solvers.screened)
    where the packing is frictionless and large enough for its solver to be MPRGP (more than
    compute.solvers.AUTO_QP_BODIES bodies).

    In a compressed soft packing most rows of the Verlet skin stay open, and MPRGP's products
    grow with the rows of each soft body, their dense blocks with the square: the 1500-disk
    frictionless runs' contact solves cost markedly less, for the same φ
    (benchmarks/results/screened_rows.md). The small frictionless packings, solved by NLGS and
    block Gauss-Seidel, keep every row: the 30-disk default's runs took other paths with it and
    were not faster in all. Frictional runs keep every row: warm-started NLGS gains
    nothing from it at N = 1500 (the same file)."""
    from compute.solvers import AUTO_QP_BODIES

    return {"solver.contact_screening": 0.1} if friction == 0.0 and bodies > AUTO_QP_BODIES else {}


def rigid_soft_rows(element: str = "T3") -> dict:
    """Contact rows of rigid disks against the boundaries of soft disks of ``element``.

    Node-disk rows hold a soft body's nodes off a rigid disk, not the segments between them.
    The nodes slide around a pressed disk, the segment between them stretches and the disk
    wedges through it: mixtures then fail at high pressure (an inverted element, a Newton stall)
    or count phi above 1. Rows against the segments too (compute.contact.soft_rows) keep them
    complete (benchmarks/results/rigid_soft_rows.md). Without friction the nodes slide freely
    and most mixtures wedge; with friction fewer do, but the 1500-disk frictional runs wedged as
    well, so every T3 mixture gets the segment rows. T6 disks keep the node rows: their
    boundaries have twice the nodes, and with segment rows their half-edges under pressed disks
    oscillate so that stages may not end. Only a scene holding both rigid and soft disks makes
    the segment rows (compute.contact.families)."""
    return {"solver.rigid_soft_rows": "nodes_and_segments"} if element == "T3" else {}


def choose_deformable(radii: np.ndarray, kappa: float, rng: np.random.Generator | None = None) -> np.ndarray:
    """Boolean mask (n,) of the disks of ``radii`` (n,) that become deformable.

    A random, position-independent choice whose total area Σ π r² is the closest reachable by a
    prefix of a random permutation (plus one swap) to κ V_p, V_p = Σ π r² over all disks.
    κ = 0 gives no soft disk, κ = 1 all of them.
    """
    radii = np.asarray(radii, dtype=float)
    if radii.ndim != 1 or len(radii) == 0 or np.any(radii <= 0) or not np.all(np.isfinite(radii)):
        raise ValueError(f"radii: expected a non-empty 1D array of positive radii, got shape {radii.shape}")
    if not 0.0 <= kappa <= 1.0:
        raise ValueError(f"kappa: expected 0 <= kappa <= 1, got {kappa}")
    rng = rng or np.random.default_rng()
    n = len(radii)
    area = np.pi * radii**2
    target = kappa * area.sum()
    order = rng.permutation(n)
    cumulative = np.concatenate([[0.0], np.cumsum(area[order])])
    k = int(np.argmin(np.abs(cumulative - target)))      # first k disks of the permutation
    chosen = np.zeros(n, dtype=bool)
    chosen[order[:k]] = True
    if 0 < k < n:  # one swap: the last chosen disk against the unchosen disk that fits best
        last, rest = order[k - 1], order[k:]
        error = cumulative[k] - target
        swapped = error - area[last] + area[rest]
        best = int(np.argmin(np.abs(swapped)))
        if abs(swapped[best]) < abs(error):
            chosen[last], chosen[rest[best]] = False, True
    return chosen


def mixture_scene(rigid_scene: str | Path, folder: str | Path, kappa: float, friction: float,
                  rng: np.random.Generator | None = None, *, element: str = "T3", n_elements: int = 92,
                  volumetric: str = "standard", young: float = 1.0, poisson: float = 0.495,
                  parameters: dict | None = None) -> tuple[Path, np.ndarray]:
    """Write ``folder`` (scene.toml + bodies.vtu): the rigid scene ``rigid_scene`` (a jammed
    packing of rigid disks, read from its files) with a fraction ``kappa`` of its particle
    volume replaced by neo-Hookean disks (:func:`choose_deformable`), each meshed with about
    ``n_elements`` triangles of type ``element`` (one reference mesh, scaled and translated).

    Every pair of materials present interacts with a Coulomb law of coefficient ``friction``
    (walls are frictionless). ``parameters``: the walls/loading/solver/output tables of the new
    scene (as in pre.scene.default_parameters); by default those of the rigid scene. The box is
    always the rigid scene's. Returns the folder and the mask (n,) of the deformable bodies.
    """
    from compute.scene import read_scene
    from pre.mesh import reference_disk_mesh
    from pre.scene import contact_laws, neo_hookean_material, rigid_material, write_scene

    rigid = read_scene(rigid_scene)
    if rigid.deformable or any(m.kind != "rigid" for m in rigid.materials.values()):
        raise ValueError(f"{rigid.path}: expected a scene of rigid disks only")
    n = rigid.n_bodies
    centres = np.zeros((n, 2))
    centres[rigid.rigid_ids] = rigid.rigid_centres
    radii = np.asarray(rigid.radius, dtype=float)
    soft = choose_deformable(radii, kappa, rng)

    params = copy.deepcopy(parameters) if parameters is not None else copy.deepcopy(rigid.raw)
    params.pop("bodies", None)
    params["walls"] = {**params["walls"], **dict(zip(("xmin", "xmax", "ymin", "ymax"), rigid.walls.bounds))}
    params["materials"] = {RIGID: rigid_material(rigid.materials[rigid.material_names[0]].density),
                           SOFT: neo_hookean_material(element, volumetric, young, poisson)}
    params["interactions"] = contact_laws([RIGID, SOFT], friction)
    meshes = {}
    if soft.any():
        reference = reference_disk_mesh(n_elements, element)
        for b in np.flatnonzero(soft):
            m = reference.placed(centres[b], radii[b])
            meshes[int(b)] = (np.array(m.points), np.array(m.cells), element)
    materials = [SOFT if s else RIGID for s in soft]
    return write_scene(folder, params, centres, radii, materials, meshes=meshes), soft
