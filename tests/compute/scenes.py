"""Small scenes for the compute tests, written through pre like any user scene."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from compute.model import Model
from compute.stepping.moreau_jean import Stepper
from compute.scene import read_scene
from pre.scene import default_parameters, write_scene


def fixed_box_parameters(bounds, friction: float, gravity, time_step: float, tol: float = 1e-10) -> dict:
    """Walls held still (velocity control at speed 0), gravity, a tight NLGS tolerance."""
    p = default_parameters(bounds, friction, 1.0, [1.0])
    p["walls"]["control"] = "velocity"
    p["loading"].update(velocity=0.0, duration=1.0, gravity=list(gravity))
    p["solver"].update(time_step=time_step, nlgs_tolerance=tol, nlgs_max_sweeps=100000, theta=1.0)
    return p


def model_of(folder: Path, params: dict, centres, radii, materials) -> tuple[Model, object]:
    """Write the scene, read it back through compute's validation, return (model, stepper)."""
    write_scene(folder, params, np.asarray(centres, float), np.asarray(radii, float), materials)
    model = Model(read_scene(folder))
    return model, Stepper(model)
