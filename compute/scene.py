"""Reading and validating a scene folder (``scene.toml`` + the bodies file).

Every table and key is declared once in :mod:`compute.schema` (type, unit, range, default, doc;
docs/FORMATS.md shows it). Every field that changes physics is required; optional keys are
switches and numerical settings with the defaults the schema states. Unknown keys are errors.
Every error is a :class:`~compute.errors.SceneError` naming the file, the field and what was
expected. A file of an older ``schema_version`` is read in the current layout
(:func:`compute.schema.migrate`).
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from compute.bodies_io import OVERLAP_TOLERANCE, DeformableBody, read_bodies
from compute import files, schema
from compute.errors import InputError, SceneError

SCENE_FILE = "scene.toml"
WALL_NAMES = ("xmin", "xmax", "ymin", "ymax")


@dataclass(frozen=True)
class Material:
    """A body material. ``kind`` is ``"rigid"`` or ``"neo_hookean"``."""

    name: str
    kind: str
    density: float
    young: float = math.inf
    poisson: float = 0.0
    element: str = ""
    volumetric: str = ""
    fixed: bool = False  # rigid only: a body that never moves (supports, obstacles)


@dataclass(frozen=True)
class Walls:
    """Four frictionless walls; ``bounds`` = (xmin, xmax, ymin, ymax)."""

    bounds: tuple[float, float, float, float]
    mass: float
    control: str
    damping_inertial_number: float
    damping_ratio: float = 0.0


@dataclass(frozen=True)
class Loading:
    """The loading program: pressure stages (or one velocity stage) and the equilibrium test."""

    pressures: tuple[float, ...]
    velocity: float
    duration: float
    phi_tolerance: float
    inertial_tolerance: float
    check_every: int
    max_steps_per_stage: int
    stall_steps: int  # 0: no stall rule (compute.stall)
    gravity: tuple[float, float]
    force_tolerance: float  # 0: no wall force-balance check


@dataclass(frozen=True)
class Solver:
    """Time-stepping and contact-solver settings (``contact_tolerance`` and ``nlgs_max_sweeps`` hold
    for whichever contact solver ``contact`` chooses; ``contact_tolerance`` for the Newton loop's
    contact test too)."""

    time_step: float
    theta: float
    contact_tolerance: float
    contact_error: str  # the error measure of contact_tolerance (compute.contact.residual.Measure)
    penetration_bound: float  # in mean diameters, 0: none
    nlgs_max_sweeps: int
    relaxation: float
    skin: float
    newton_tolerance: float
    newton_max_iterations: int
    contact: str  # contact solver: "auto", "nlgs", "block", "nlgs_block", "interior_point", "nlgs_ip", "cone_point", "mprgp" (compute.solvers.for_scene)
    rigid_soft_rows: str  # "nodes" or "nodes_and_segments" (compute.contact.soft_rows, segment-disk)
    hold_rotation: bool  # soft bodies' angular momentum about their centroid held at zero (compute.bodies.soft)
    mass_scaling: float  # c of the soft bodies' inertia factor max(1, c P h² / (ρ <d>²)) in a stage (compute.bodies.soft)
    contact_screening: float  # margin of the contacts solved first, 0: all (compute.solvers.screened)
    step: str  # step strategy: "auto", "fixed_point", "active_set" (compute.stepping.strategies)


@dataclass(frozen=True)
class Output:
    frames: str
    every_steps: int
    checkpoint_every_steps: int


@dataclass
class Scene:
    """A validated scene.

    Rigid disks: ``rigid_ids`` (nr,), ``rigid_centres`` (nr, 2), ``rigid_radii`` (nr,).
    ``body_material`` (n_bodies,) indexes ``material_names``; ``radius`` (n_bodies,) is the
    nominal radius of every body; ``friction`` (n_mat, n_mat) the Coulomb coefficients.
    """

    path: Path
    materials: dict[str, Material]
    material_names: list[str]
    body_material: np.ndarray
    radius: np.ndarray
    rigid_ids: np.ndarray
    rigid_centres: np.ndarray
    rigid_radii: np.ndarray
    deformable: list[DeformableBody]
    friction: np.ndarray
    walls: Walls
    loading: Loading
    solver: Solver
    output: Output
    raw: dict = field(repr=False, default_factory=dict)  # scene.toml as read, in the current layout (migrated)

    @property
    def n_bodies(self) -> int:
        return len(self.body_material)

    @property
    def mean_diameter(self) -> float:
        return float(2.0 * self.radius.mean())


def read_scene(scene_dir: str | Path, bodies_outside: bool = False) -> Scene:
    """Read and validate the scene folder ``scene_dir`` (``scene.toml`` and its bodies file).

    The bodies file must lie inside the scene folder unless ``bodies_outside`` (``python -m
    compute --bodies-outside-scene``): a scene is a folder that can be copied, archived and
    resumed as a whole, and a path such as ``../../x/bodies.vtu`` breaks that silently."""
    scene_dir = Path(scene_dir)
    file = scene_dir / SCENE_FILE
    data = schema.migrate(file, read_toml(file))
    tables = parse_parameters(file, data)
    bodies_file = scene_dir / tables["bodies"]["file"]
    if not bodies_outside and not bodies_file.resolve().is_relative_to(scene_dir.resolve()):
        raise SceneError(file, "bodies.file", "a file inside the scene folder (or python -m compute "
                         "--bodies-outside-scene)", tables["bodies"]["file"])
    if not files.is_file(bodies_file, SceneError):
        raise SceneError(file, "bodies.file", "the name of an existing file in the scene folder",
                         tables["bodies"]["file"])
    bodies = read_bodies(bodies_file, tables["material_names"], tables["materials"])
    _check_inside_box(bodies_file, bodies, tables["walls"])
    return Scene(path=scene_dir, materials=tables["materials"], material_names=tables["material_names"],
                 friction=tables["friction"], walls=tables["walls"], loading=tables["loading"],
                 solver=tables["solver"], output=tables["output"], raw=data, **bodies)


def read_toml(file: str | Path, error: type[InputError] = SceneError) -> dict:
    """The parsed TOML of a scene parameter file (a scene's, or its copy in an output folder);
    a missing, unreadable or malformed file raises ``error`` naming it."""
    if not files.is_file(file, error):
        raise error(file, "<file>", "an existing scene parameter file")
    try:
        return tomllib.loads(files.read_text(file, error))
    except tomllib.TOMLDecodeError as exc:
        raise error(file, "<syntax>", "valid TOML", str(exc)) from None


def read_parameters(file: str | Path, error: type[InputError] = SceneError) -> dict:
    """The validated parameters of a scene parameter file alone, without its bodies file (what
    post and the studies read of a run: the copy OUT/scene.toml): :func:`parse_parameters`'s
    tables. Every problem raises ``error`` naming the file and the field."""
    try:
        return parse_parameters(file, read_toml(file, error))
    except SceneError as exc:
        if error is SceneError:
            raise
        raise error(exc.file, exc.field, exc.expected, exc.got) from None


def parse_parameters(file, data: dict) -> dict:
    """The tables of a scene's parameters ``data`` (as read from ``file``; of any schema
    version, :func:`compute.schema.migrate`), validated against :mod:`compute.schema`: materials,
    material_names, friction, walls, loading, solver, output and the raw [bodies] table. Raises
    SceneError naming ``file`` and the field."""
    data = schema.migrate(file, data)
    schema.validate(file, "", data, schema.TOP, extra=("bodies", "materials", "interactions", *schema.SETTINGS))
    materials = _read_materials(file, data.get("materials"))
    bodies = schema.validate(file, "bodies.", data.get("bodies"), schema.BODIES)
    names = bodies["materials"]
    for n in names:
        if n not in materials:
            raise SceneError(file, "bodies.materials", f"names defined in [materials] ({sorted(materials)})", n)
    w = schema.validate(file, "walls.", data.get("walls"), schema.WALLS)
    bounds = tuple(w[k] for k in WALL_NAMES)
    if not (bounds[0] < bounds[1] and bounds[2] < bounds[3]):
        raise SceneError(file, "walls.xmin/xmax/ymin/ymax", "xmin < xmax and ymin < ymax", bounds)
    walls = Walls(bounds, w["mass"], w["control"], w["damping_inertial_number"], w["damping_ratio"])
    ld = schema.validate(file, "loading.", data.get("loading"), schema.LOADING, context={"control": walls.control})
    if walls.control == "pressure" and not ld["pressures"]:
        raise SceneError(file, "loading.pressures", "a non-empty list of positive numbers", ld["pressures"])
    loading = Loading(**{**ld, "pressures": tuple(ld["pressures"]), "gravity": tuple(ld["gravity"])})
    _check_pressure_over_young(file, materials, loading.pressures)
    friction = _read_interactions(file, data, names)
    solver = Solver(**schema.validate(file, "solver.", data.get("solver"), schema.SOLVER))
    if solver.contact == "mprgp" and friction.max() > 0.0:
        raise SceneError(file, "solver.contact", "a contact solver for friction ('mprgp' solves frictionless "
                         "contact only: every [[interactions]] law frictionless or of friction 0)", solver.contact)
    return dict(materials=materials, material_names=list(names), friction=friction,
                walls=walls, loading=loading, solver=solver,
                output=Output(**schema.validate(file, "output.", data.get("output"), schema.OUTPUT)), bodies=bodies)


def _read_materials(file, tab) -> dict[str, Material]:
    if not isinstance(tab, dict) or not tab:
        raise SceneError(file, "materials", "a table of one or more [materials.NAME] tables", tab)
    out = {}
    for name, m in tab.items():
        p = f"materials.{name}."
        kind = m.get("kind") if isinstance(m, dict) else None
        if not isinstance(kind, str) or kind not in schema.MATERIALS:
            raise SceneError(file, p + "kind", "one of " + ", ".join(map(repr, schema.MATERIALS)), kind)
        v = schema.validate(file, p, m, schema.MATERIALS[kind])
        if kind == "neo_hookean" and v["element"] == "T3" and v["volumetric"] == "mean_dilatation":
            raise SceneError(file, p + "volumetric", "'standard' for T3 elements (one Gauss point)", v["volumetric"])
        out[name] = Material(name, **v)
    return out


def _check_pressure_over_young(file, materials: dict[str, Material], pressures: tuple[float, ...]) -> None:
    """The largest pressure over each soft material's Young modulus within what the elements
    handle, schema.PRESSURE_OVER_YOUNG: beyond it the single particle's elements invert
    (benchmarks/results/design_figures.md)."""
    top = max(pressures, default=0.0)
    for m in materials.values():
        if m.kind == "neo_hookean" and top > schema.PRESSURE_OVER_YOUNG * m.young:
            raise SceneError(file, "loading.pressures", f"pressures up to {schema.PRESSURE_OVER_YOUNG:g} x the young "
                             f"modulus of material '{m.name}' ({m.young:g}): the elements do not handle P/E above it",
                             top)


def _read_interactions(file, data: dict, names: list[str]) -> np.ndarray:
    items = data.get("interactions")
    if not isinstance(items, list) or not items:
        raise SceneError(file, "interactions", "a non-empty array of tables [[interactions]]", items)
    index = {n: i for i, n in enumerate(names)}
    friction = np.full((len(names), len(names)), np.nan)
    for k, it in enumerate(items):
        p = f"interactions[{k}]."
        v = schema.validate(file, p, it, schema.INTERACTION)
        pair = v["between"]
        if not all(x in index for x in pair):
            raise SceneError(file, p + "between", f"two material names among {names}", pair)
        a, b = index[pair[0]], index[pair[1]]
        if not np.isnan(friction[a, b]):
            raise SceneError(file, p + "between", "each pair of materials once", pair)
        friction[a, b] = friction[b, a] = v["friction"] if v["law"] == "coulomb" else 0.0
    missing = [(names[a], names[b]) for a in range(len(names)) for b in range(a, len(names))
               if np.isnan(friction[a, b])]
    if missing:
        raise SceneError(file, "interactions", f"a law for every pair of materials (missing {missing})")
    return friction


def _check_inside_box(file: Path, bodies: dict, walls: Walls) -> None:
    """Every body inside the box, up to the overlap tolerance of a jammed NSCD state."""
    c, rad = bodies["rigid_centres"], bodies["rigid_radii"]
    slack = OVERLAP_TOLERANCE * float(bodies["radius"].min())
    xmin, xmax, ymin, ymax = np.array(walls.bounds) + np.array([-slack, slack, -slack, slack])
    out = (c[:, 0] - rad < xmin) | (c[:, 0] + rad > xmax) | (c[:, 1] - rad < ymin) | (c[:, 1] + rad > ymax)
    for b in bodies["deformable"]:
        p = b.points
        if p[:, 0].min() < xmin or p[:, 0].max() > xmax or p[:, 1].min() < ymin or p[:, 1].max() > ymax:
            raise SceneError(file, f"points of body {b.body}", "inside the walls' box")
    if out.any():
        i = int(bodies["rigid_ids"][np.argmax(out)])
        raise SceneError(file, f"radius/points of body {i}", "a disk inside the walls' box")
