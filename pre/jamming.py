"""Bringing a loose packing to the jammed state with the compute stage, as LMGC90 users do.

The loose packing is written as a scene whose walls are pushed by a small pressure with the
wall damping that keeps the inertial number near ``inertial_number``; compute runs it to
equilibrium; the jammed positions and box are read back from its last frame (a file, not
compute's memory).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from pre.scene import default_parameters, overridden, write_scene


def jam(workdir: str | Path, centres: np.ndarray, radii: np.ndarray, box: tuple[float, float, float, float],
        friction: float, pressure: float = 1.0, inertial_number: float = 1e-3,
        overrides: dict | None = None, log=None) -> tuple[np.ndarray, tuple[float, float, float, float]]:
    """Compress the rigid disks centres (n, 2), radii (n,) in ``box`` at ``pressure`` until jammed.

    Runs in ``workdir``/scene and ``workdir``/out; returns the jammed centres (n, 2) and box.
    ``overrides`` maps "table.key" to a value of the scene parameters (e.g. "solver.time_step").
    """
    from compute.output import frame_path
    from compute.run import run

    from meshio import vtu

    workdir = Path(workdir)
    params = default_parameters(box, friction, float(2 * radii.mean()), [pressure])
    params["walls"]["damping_inertial_number"] = inertial_number
    write_scene(workdir / "scene", overridden(params, overrides), centres, radii, ["rigid"] * len(radii))
    state = run(workdir / "scene", workdir / "out", log=log)
    last = state.frame - 1
    bodies = vtu.read(frame_path(workdir / "out", "bodies", last))
    walls = vtu.read(frame_path(workdir / "out", "walls", last))
    order = np.argsort(np.asarray(bodies.cell_data["body"][0]))
    vertex = bodies.cells[0].data[:, 0]
    jammed = np.asarray(bodies.points)[vertex[order], :2]
    position = np.asarray(walls.cell_data["position"][0], float)
    return jammed, tuple(float(x) for x in position)


def jammed_rigid_scene(workdir: str | Path, n: int, friction: float, seed: int, pressures: list[float],
                       loose_phi: float = 0.5, overrides: dict | None = None, log=None) -> Path:
    """Write ``workdir``/scene: n polydisperse rigid disks jammed at friction ``friction``, with the
    loading program ``pressures``. The preparation run is kept in ``workdir``/jamming."""
    from pre.packing import polydisperse_radii, random_loose_packing

    rng = np.random.default_rng(seed)
    radii = polydisperse_radii(n, rng=rng)
    centres, box = random_loose_packing(radii, loose_phi, rng)
    return _jammed_scene(workdir, centres, radii, box, friction, pressures, overrides, log)


def relaxed_rigid_scene(rigid_scene: str | Path, workdir: str | Path, friction: float,
                        overrides: dict | None = None, log=None) -> Path:
    """Write ``workdir``/scene: the jammed rigid disks of the scene folder ``rigid_scene``, jammed
    again from their positions with the friction ``friction``, with that scene's loading program.

    Why: a packing jammed with friction is not in equilibrium with less of it. Given a smaller
    coefficient it flows until it jams again, denser, and that flow at a small pressure is much
    cheaper to compute with rigid disks than with the finite-element disks that will replace
    some of them. The run is kept in ``workdir``/jamming; the bodies keep their order."""
    from compute.scene import read_scene

    scene = read_scene(rigid_scene)
    if scene.deformable or len(scene.rigid_ids) != scene.n_bodies:
        raise ValueError(f"{scene.path}: expected a scene of rigid disks only")
    centres, radii = np.zeros((scene.n_bodies, 2)), np.zeros(scene.n_bodies)
    centres[scene.rigid_ids], radii[scene.rigid_ids] = scene.rigid_centres, scene.rigid_radii
    return _jammed_scene(workdir, centres, radii, tuple(scene.walls.bounds), friction,
                         list(scene.loading.pressures), overrides, log)


def _jammed_scene(workdir, centres, radii, box, friction, pressures, overrides, log) -> Path:
    """Jam (:func:`jam`) the rigid disks centres (n, 2), radii (n,) in ``box`` at the least of
    ``pressures`` in ``workdir``/jamming, then write them as ``workdir``/scene with the loading
    program ``pressures``."""
    workdir = Path(workdir)
    centres, box = jam(workdir / "jamming", centres, radii, box, friction, pressure=min(pressures),
                       overrides=overrides, log=log)
    params = overridden(default_parameters(box, friction, float(2 * radii.mean()), pressures), overrides)
    return write_scene(workdir / "scene", params, centres, radii, ["rigid"] * len(radii))
