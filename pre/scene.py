"""Writing a scene folder: ``scene.toml`` (parameters) and ``bodies.vtu`` (geometry).

The parameter dictionary mirrors docs/FORMATS.md table by table; :func:`default_parameters`
gives a complete, documented starting point that studies then adjust. compute validates
everything on reading, so a scene written here is checked once more before it runs.
"""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import tomli_w

from compute.bodies_io import write_bodies
from compute.scene import SCHEMA_VERSION

BODIES_FILE = "bodies.vtu"


def default_parameters(bounds: tuple[float, float, float, float], friction: float, mean_diameter: float,
                       pressures: list[float], density: float = 1.0) -> dict:
    """Parameters of a rigid-disk compaction in reduced units (⟨d⟩, ρ, P set the scales).

    The time step keeps the displacement per step small against ⟨d⟩ at the velocities of a
    quasi-static compression (I ~ 1e-3), and the walls weigh about a row of particles.
    """
    p_ref = min(pressures)
    t_ref = mean_diameter * np.sqrt(density / p_ref)  # time for a grain to move by d under P
    width = bounds[1] - bounds[0]
    return {
        "schema_version": SCHEMA_VERSION,
        "materials": {"rigid": {"kind": "rigid", "density": density}},
        "interactions": [{"between": ["rigid", "rigid"], "law": "coulomb", "friction": friction}],
        "walls": {"xmin": bounds[0], "xmax": bounds[1], "ymin": bounds[2], "ymax": bounds[3],
                  "mass": density * np.pi * mean_diameter**2 / 4 * width / mean_diameter,
                  "control": "pressure", "damping_inertial_number": 1e-3},
        "loading": {"pressures": list(pressures), "phi_tolerance": 1e-4, "inertial_tolerance": 1e-4,
                    "force_tolerance": 1e-3,
                    "check_every": 20, "max_steps_per_stage": 200000, "gravity": [0.0, 0.0]},
        "solver": {"time_step": 0.02 * t_ref, "theta": 1.0, "nlgs_tolerance": 1e-6,
                   "nlgs_max_sweeps": 2000, "relaxation": 1.0, "skin": 0.1},
        "output": {"frames": "stages", "every_steps": 0, "checkpoint_every_steps": 1000},
    }


def write_scene(folder: str | Path, parameters: dict, centres: np.ndarray, radii: np.ndarray,
                material: list[str] | np.ndarray, meshes: dict | None = None) -> Path:
    """Write ``folder``/scene.toml and ``folder``/bodies.vtu.

    centres (n, 2), radii (n,): every body's centre and nominal radius; ``material`` (n,) the
    material name of each body (keys of ``parameters["materials"]``); ``meshes`` maps a
    deformable body id to (points (m, 2), cells (ne, 3|6), "T3"|"T6").
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    names = sorted(set(material), key=lambda n: list(parameters["materials"]).index(n))
    index = {n: i for i, n in enumerate(names)}
    params = copy.deepcopy(parameters)
    params["bodies"] = {"file": BODIES_FILE, "materials": names}
    params["interactions"] = [it for it in params["interactions"] if set(it["between"]) <= set(names)]
    params["materials"] = {n: m for n, m in params["materials"].items() if n in names}
    (folder / "scene.toml").write_text(tomli_w.dumps(_plain(params)))
    write_bodies(folder / BODIES_FILE, np.asarray(centres, float), np.asarray(radii, float),
                 np.array([index[m] for m in material], dtype=np.int64), meshes=meshes)
    return folder


def _plain(x):
    """numpy scalars and arrays to TOML-serialisable Python values."""
    if isinstance(x, dict):
        return {k: _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple, np.ndarray)):
        return [_plain(v) for v in x]
    if isinstance(x, np.generic):
        return x.item()
    return x
