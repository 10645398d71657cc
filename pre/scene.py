"""Writing a scene folder: ``scene.toml`` (parameters) and ``bodies.vtu`` (geometry).

Parameters are built from :mod:`compute.schema` (:func:`scene_parameters`), never written out
as nested dicts by hand: settings are given by key name, unknown or missing keys are errors, and
every optional key not given is written with its default, so that a scene file states every
value it runs with. :func:`write_scene` validates the parameters with compute's own reader
before it writes anything. :func:`default_parameters` is a documented starting point for rigid
compactions that studies then adjust (:func:`overridden`).
"""

from __future__ import annotations

import copy
import itertools
from pathlib import Path

import numpy as np
import tomli_w

from compute import schema
from compute.bodies_io import write_bodies
from compute.errors import SceneError
from compute.scene import parse_parameters

BODIES_FILE = "bodies.vtu"
PARAMETERS = "<scene parameters>"  # the 'file' named by errors in parameters not yet written


def rigid_material(density: float = 1.0, fixed: bool = False) -> dict:
    """A ``[materials.NAME]`` table of rigid disks."""
    return {"kind": "rigid", "density": float(density), "fixed": bool(fixed)}


def neo_hookean_material(element: str = "T3", volumetric: str = "standard", young: float = 1.0,
                         poisson: float = 0.495, density: float = 1.0) -> dict:
    """A ``[materials.NAME]`` table of neo-Hookean disks: E = 1, ν = 0.495 by default (the paper's).

    ``volumetric`` is "standard" by default, for T6 too (the only one compute accepts for
    one-point T3 elements). Measured for T6 (studies/single_particle/README.md, "The best T6
    disk near 92 elements"): the standard term is the closer of the two to the converged
    single-particle curve at every mesh of about 92 elements, and it carries soft mixtures to
    P/E = 1, where mean-dilatation disks drift far from J/J_ref = 1 pointwise and stop."""
    if element not in ("T3", "T6"):
        raise ValueError(f"element: expected 'T3' or 'T6', got {element!r}")
    return {"kind": "neo_hookean", "density": float(density), "young": float(young),
            "poisson": float(poisson), "element": element, "volumetric": volumetric}


def contact_laws(names, friction: float) -> list[dict]:
    """``[[interactions]]`` for every unordered pair of the materials ``names``: Coulomb with
    coefficient ``friction``, frictionless when it is 0."""
    law = {"law": "coulomb", "friction": float(friction)} if friction > 0 else {"law": "frictionless"}
    return [{"between": [a, b], **law} for a, b in itertools.combinations_with_replacement(list(names), 2)]


def scene_parameters(materials: dict[str, dict], interactions: list[dict], **settings) -> dict:
    """Complete, validated scene parameters.

    ``settings``: keys of the [walls], [loading], [solver] and [output] tables by name (they are
    unique across those tables, :func:`compute.schema.table_of`), e.g. ``xmin=0.0,
    time_step=0.5, pressures=[1e-3]``. Required keys must be given; optional keys not given take
    their schema default (keys required only under a condition, such as loading.velocity under
velocity control, are written only when given). Raises SceneError on an unknown, missing or invalid key."""
    params = {"schema_version": schema.SCHEMA_VERSION, "materials": copy.deepcopy(materials),
              "interactions": copy.deepcopy(interactions), **{t: {} for t in schema.SETTINGS}}
    for key, value in settings.items():
        try:
            params[schema.table_of(key)][key] = _plain(value)
        except KeyError as exc:
            raise SceneError(PARAMETERS, key, exc.args[0]) from None
    for table, keys in schema.SETTINGS.items():
        for k in keys:
            if k.name not in params[table] and not k.required and k.when is None:
                params[table][k.name] = copy.deepcopy(k.default)
    _validate(PARAMETERS, params)
    return params


def overridden(params: dict, overrides: dict | None, file=PARAMETERS) -> dict:
    """A copy of ``params`` (of any schema version: written in the current one,
    :func:`compute.schema.migrate`) with ``overrides`` ("table.key" -> value) applied and
    validated (errors name ``file``)."""
    out = schema.migrate(file, copy.deepcopy(params))
    for dotted, value in (overrides or {}).items():
        table, _, key = dotted.partition(".")
        known = [f"{t}.{k.name}" for t, keys in schema.SETTINGS.items() for k in keys]
        if dotted not in known:
            raise SceneError(file, dotted, schema.unknown_key(dotted, known))
        out[table][key] = _plain(value)
    _validate(file, out)
    return out


def default_parameters(bounds: tuple[float, float, float, float], friction: float, mean_diameter: float,
                       pressures: list[float], density: float = 1.0) -> dict:
    """Parameters of a rigid-disk compaction in reduced units (⟨d⟩, ρ, P set the scales).

    The time step keeps the displacement per step small against ⟨d⟩ at the velocities of a
    quasi-static compression (I ~ 1e-3), and the walls weigh about a row of particles.
    """
    p_ref = min(pressures)
    t_ref = mean_diameter * np.sqrt(density / p_ref)  # time for a grain to move by d under P
    width = bounds[1] - bounds[0]
    return scene_parameters(
        {"rigid": rigid_material(density)}, contact_laws(["rigid"], friction),
        **dict(zip(("xmin", "xmax", "ymin", "ymax"), bounds)),
        mass=density * np.pi * mean_diameter**2 / 4 * width / mean_diameter, control="pressure",
        damping_inertial_number=1e-3,
        pressures=list(pressures), phi_tolerance=1e-4, inertial_tolerance=1e-4, force_tolerance=1e-3,
        check_every=20, max_steps_per_stage=200000, gravity=[0.0, 0.0],
        time_step=0.02 * t_ref, theta=1.0, contact_tolerance=1e-6, nlgs_max_sweeps=2000, relaxation=1.0, skin=0.1,
        frames="stages", every_steps=0, checkpoint_every_steps=1000)


def _validate(file, params: dict) -> None:
    """compute's own checks of the parameter tables (the bodies table filled in if absent)."""
    bodies = params.get("bodies", {"file": BODIES_FILE, "materials": list(params.get("materials") or {})})
    parse_parameters(file, {**params, "bodies": bodies})


def write_scene(folder: str | Path, parameters: dict, centres: np.ndarray, radii: np.ndarray,
                material: list[str] | np.ndarray, meshes: dict | None = None) -> Path:
    """Write ``folder``/scene.toml and ``folder``/bodies.vtu.

    centres (n, 2), radii (n,): every body's centre and nominal radius; ``material`` (n,) the
    material name of each body (keys of ``parameters["materials"]``); ``meshes`` maps a
    deformable body id to (points (m, 2), cells (ne, 3|6), "T3"|"T6").
    """
    folder = Path(folder)
    names = sorted(set(material), key=lambda n: list(parameters["materials"]).index(n))
    index = {n: i for i, n in enumerate(names)}
    params = copy.deepcopy(parameters)
    params["bodies"] = {"file": BODIES_FILE, "materials": names}
    params["interactions"] = [it for it in params["interactions"] if set(it["between"]) <= set(names)]
    params["materials"] = {n: m for n, m in params["materials"].items() if n in names}
    params = _plain(params)
    _validate(folder / "scene.toml", params)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "scene.toml").write_text(tomli_w.dumps(params))
    write_bodies(folder / BODIES_FILE, np.asarray(centres, float), np.asarray(radii, float),
                 np.array([index[m] for m in material], dtype=np.int64), meshes=meshes)
    return folder


def copy_scene(source: str | Path, folder: str | Path, overrides: dict) -> Path:
    """Copy the scene folder ``source`` to ``folder`` with ``overrides`` ("table.key" -> value,
    as :func:`overridden`, validated) applied to its scene.toml; returns ``folder``."""
    import shutil
    import tomllib

    source, folder = Path(source), Path(folder)
    params = overridden(tomllib.loads((source / "scene.toml").read_text()), overrides, source / "scene.toml")
    shutil.copytree(source, folder)
    (folder / "scene.toml").write_text(tomli_w.dumps(params))
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
