"""Small scenes for the compute tests, written through pre like any user scene."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from compute.model import Model
from compute.stepping.moreau_jean import Stepper
from compute.scene import read_scene
from pre.packing import polydisperse_radii, random_loose_packing
from pre.scene import default_parameters, write_scene


def fixed_box_parameters(bounds, friction: float, gravity, time_step: float, tol: float = 1e-10) -> dict:
    """Walls held still (velocity control at speed 0), gravity, a tight NLGS tolerance."""
    p = default_parameters(bounds, friction, 1.0, [1.0])
    p["walls"]["control"] = "velocity"
    p["loading"].update(velocity=0.0, duration=1.0, gravity=list(gravity))
    p["solver"].update(time_step=time_step, contact_tolerance=tol, nlgs_max_sweeps=100000, theta=1.0)
    return p


def model_of(folder: Path, params: dict, centres, radii, materials) -> tuple[Model, object]:
    """Write the scene, read it back through compute's validation, return (model, stepper)."""
    write_scene(folder, params, np.asarray(centres, float), np.asarray(radii, float), materials)
    model = Model(read_scene(folder))
    return model, Stepper(model)


def rigid_scene(folder: Path, n: int, seed: int, checkpoint_every: int, frame_every: int) -> Path:
    """``n`` rigid disks, a loose packing of ``seed``, compressed in two stages (P = 1, 2) with
    h = 0.1, a checkpoint every ``checkpoint_every`` steps and a frame every ``frame_every``."""
    rng = np.random.default_rng(seed)
    radii = polydisperse_radii(n, rng=rng)
    centres, box = random_loose_packing(radii, 0.5, rng)
    p = default_parameters(box, 0.3, 1.0, [1.0, 2.0])
    p["solver"]["time_step"] = 0.1
    p["output"].update(checkpoint_every_steps=checkpoint_every, every_steps=frame_every)
    return write_scene(folder, p, centres, radii, ["rigid"] * n)


def finished_rigid_run(folder: Path) -> tuple[Path, Path]:
    """(scene, output folder) of ``small_rigid_scene`` computed to its end under ``folder``."""
    from compute.__main__ import main

    scene = small_rigid_scene(folder / "scene")
    assert main([str(scene), "--out", str(folder / "out")]) == 0
    return scene, folder / "out"


def small_rigid_scene(folder: Path) -> Path:
    """20 rigid disks compressed in two stages, a checkpoint every 10 steps and a frame every 40."""
    return rigid_scene(folder, 20, 4, 10, 40)
