"""Reading and validating a scene folder (``scene.toml`` + the bodies file).

The file contract is ``docs/FORMATS.md``. Every field that changes physics is required: nothing
is silently defaulted. Every error is a :class:`~compute.errors.SceneError` naming the file, the
field and what was expected.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from compute.bodies_io import OVERLAP_TOLERANCE, DeformableBody, read_bodies
from compute.errors import SceneError

SCHEMA_VERSION = 1
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
    gravity: tuple[float, float]
    force_tolerance: float = 0.0  # 0: no wall force-balance check


@dataclass(frozen=True)
class Solver:
    """Time-stepping and contact-solver settings (``nlgs_tolerance`` and ``nlgs_max_sweeps`` hold
    for whichever contact solver ``contact`` chooses)."""

    time_step: float
    theta: float
    nlgs_tolerance: float
    nlgs_max_sweeps: int
    relaxation: float
    skin: float
    newton_tolerance: float = 1e-8
    newton_max_iterations: int = 20
    contact: str = "auto"  # contact solver: "auto", "nlgs" or "block" (compute.solvers.for_scene)


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
    raw: dict = field(repr=False, default_factory=dict)

    @property
    def n_bodies(self) -> int:
        return len(self.body_material)

    @property
    def mean_diameter(self) -> float:
        return float(2.0 * self.radius.mean())


class _Reader:
    """Typed access to a TOML table with errors naming file and dotted field."""

    def __init__(self, file: Path, data: dict):
        self.file, self.data = file, data

    def table(self, key: str, parent: dict | None = None, prefix: str = "") -> dict:
        src = self.data if parent is None else parent
        value = src.get(key)
        if not isinstance(value, dict):
            raise SceneError(self.file, prefix + key, "a table", value)
        return value

    def number(self, table: dict, key: str, prefix: str, *, low: float | None = None,
               high: float | None = None, strict_low: bool = False, integer: bool = False):
        name = prefix + key
        if key not in table:
            raise SceneError(self.file, name, "a number (missing)")
        value = table[key]
        kind = "an integer" if integer else "a number"
        ok_type = int if integer else (int, float)
        if isinstance(value, bool) or not isinstance(value, ok_type) or not math.isfinite(value):
            raise SceneError(self.file, name, kind, value)
        if low is not None and (value <= low if strict_low else value < low):
            raise SceneError(self.file, name, f"{kind} {'>' if strict_low else '>='} {low}", value)
        if high is not None and value > high:
            raise SceneError(self.file, name, f"{kind} <= {high}", value)
        return value

    def choice(self, table: dict, key: str, prefix: str, options: tuple[str, ...]) -> str:
        value = table.get(key)
        if value not in options:
            raise SceneError(self.file, prefix + key, "one of " + ", ".join(map(repr, options)), value)
        return value


def read_scene(scene_dir: str | Path) -> Scene:
    """Read and validate the scene folder ``scene_dir`` (``scene.toml`` and its bodies file)."""
    scene_dir = Path(scene_dir)
    file = scene_dir / SCENE_FILE
    if not file.is_file():
        raise SceneError(file, "<file>", "an existing scene parameter file")
    try:
        data = tomllib.loads(file.read_text())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise SceneError(file, "<syntax>", "valid TOML", str(exc)) from None
    r = _Reader(file, data)
    version = r.number(data, "schema_version", "", integer=True)
    if version != SCHEMA_VERSION:
        raise SceneError(file, "schema_version", f"{SCHEMA_VERSION}", version)

    materials = _read_materials(r)
    bodies_tab = r.table("bodies")
    names = bodies_tab.get("materials")
    if not isinstance(names, list) or not names or not all(isinstance(n, str) for n in names):
        raise SceneError(file, "bodies.materials", "a non-empty list of material names", names)
    for n in names:
        if n not in materials:
            raise SceneError(file, "bodies.materials", f"names defined in [materials] ({sorted(materials)})", n)
    friction = _read_interactions(r, names)
    walls = _read_walls(r)
    loading = _read_loading(r, walls.control)
    solver = _read_solver(r)
    output = _read_output(r)

    bodies_file = bodies_tab.get("file")
    if not isinstance(bodies_file, str):
        raise SceneError(file, "bodies.file", "a file name relative to the scene folder", bodies_file)
    bodies = read_bodies(scene_dir / bodies_file, names, materials)
    _check_inside_box(scene_dir / bodies_file, bodies, walls)
    return Scene(path=scene_dir, materials=materials, material_names=list(names),
                 friction=friction, walls=walls, loading=loading, solver=solver, output=output,
                 raw=data, **bodies)


def _read_materials(r: _Reader) -> dict[str, Material]:
    tab = r.table("materials")
    out = {}
    for name, m in tab.items():
        p = f"materials.{name}."
        if not isinstance(m, dict):
            raise SceneError(r.file, f"materials.{name}", "a table", m)
        kind = r.choice(m, "kind", p, ("rigid", "neo_hookean"))
        density = r.number(m, "density", p, low=0.0, strict_low=True)
        if kind == "rigid":
            fixed = m.get("fixed", False)
            if not isinstance(fixed, bool):
                raise SceneError(r.file, p + "fixed", "true or false", fixed)
            out[name] = Material(name, kind, float(density), fixed=fixed)
            continue
        young = r.number(m, "young", p, low=0.0, strict_low=True)
        poisson = r.number(m, "poisson", p, low=-1.0, high=0.4999999, strict_low=True)
        element = r.choice(m, "element", p, ("T3", "T6"))
        volumetric = r.choice(m, "volumetric", p, ("standard", "mean_dilatation"))
        if element == "T3" and volumetric == "mean_dilatation":
            raise SceneError(r.file, p + "volumetric", "'standard' for T3 elements (one Gauss point)",
                             volumetric)
        out[name] = Material(name, kind, float(density), float(young), float(poisson), element, volumetric)
    if not out:
        raise SceneError(r.file, "materials", "at least one material")
    return out


def _read_interactions(r: _Reader, names: list[str]) -> np.ndarray:
    items = r.data.get("interactions")
    if not isinstance(items, list) or not items:
        raise SceneError(r.file, "interactions", "a non-empty array of tables [[interactions]]", items)
    index = {n: i for i, n in enumerate(names)}
    friction = np.full((len(names), len(names)), np.nan)
    for k, it in enumerate(items):
        p = f"interactions[{k}]."
        pair = it.get("between") if isinstance(it, dict) else None
        if not (isinstance(pair, list) and len(pair) == 2 and all(x in index for x in pair)):
            raise SceneError(r.file, p + "between", f"two material names among {names}", pair)
        law = r.choice(it, "law", p, ("coulomb", "frictionless"))
        mu = r.number(it, "friction", p, low=0.0) if law == "coulomb" else 0.0
        a, b = index[pair[0]], index[pair[1]]
        if not np.isnan(friction[a, b]):
            raise SceneError(r.file, p + "between", "each pair of materials once", pair)
        friction[a, b] = friction[b, a] = mu
    missing = [(names[a], names[b]) for a in range(len(names)) for b in range(a, len(names))
               if np.isnan(friction[a, b])]
    if missing:
        raise SceneError(r.file, "interactions", f"a law for every pair of materials (missing {missing})")
    return friction


def _read_walls(r: _Reader) -> Walls:
    tab = r.table("walls")
    p = "walls."
    bounds = tuple(float(r.number(tab, k, p)) for k in WALL_NAMES)
    if not (bounds[0] < bounds[1] and bounds[2] < bounds[3]):
        raise SceneError(r.file, "walls.xmin/xmax/ymin/ymax", "xmin < xmax and ymin < ymax", bounds)
    if tab.get("friction", 0.0) != 0.0:
        raise SceneError(r.file, "walls.friction", "0 (walls are frictionless)", tab.get("friction"))
    mass = r.number(tab, "mass", p, low=0.0, strict_low=True)
    control = r.choice(tab, "control", p, ("pressure", "velocity"))
    damping = r.number(tab, "damping_inertial_number", p, low=0.0) if "damping_inertial_number" in tab else 0.0
    return Walls(bounds, float(mass), control, float(damping))


def _read_loading(r: _Reader, control: str) -> Loading:
    tab = r.table("loading")
    p = "loading."
    pressures = tab.get("pressures", [])
    if control == "pressure":
        if (not isinstance(pressures, list) or not pressures
                or not all(isinstance(x, (int, float)) and not isinstance(x, bool) and x > 0 for x in pressures)):
            raise SceneError(r.file, p + "pressures", "a non-empty list of positive numbers", pressures)
    velocity = r.number(tab, "velocity", p) if control == "velocity" else 0.0
    duration = r.number(tab, "duration", p, low=0.0, strict_low=True) if control == "velocity" else 0.0
    gravity = tab.get("gravity")
    if not (isinstance(gravity, list) and len(gravity) == 2 and all(isinstance(g, (int, float)) for g in gravity)):
        raise SceneError(r.file, p + "gravity", "a list of two numbers [gx, gy]", gravity)
    return Loading(
        pressures=tuple(float(x) for x in pressures),
        velocity=float(velocity), duration=float(duration),
        phi_tolerance=float(r.number(tab, "phi_tolerance", p, low=0.0, strict_low=True)),
        inertial_tolerance=float(r.number(tab, "inertial_tolerance", p, low=0.0, strict_low=True)),
        check_every=int(r.number(tab, "check_every", p, low=1, integer=True)),
        max_steps_per_stage=int(r.number(tab, "max_steps_per_stage", p, low=1, integer=True)),
        gravity=(float(gravity[0]), float(gravity[1])),
        force_tolerance=float(r.number(tab, "force_tolerance", p, low=0.0)) if "force_tolerance" in tab else 0.0,
    )


def _read_solver(r: _Reader) -> Solver:
    tab = r.table("solver")
    p = "solver."
    extra = {}
    if "newton_tolerance" in tab:
        extra["newton_tolerance"] = float(r.number(tab, "newton_tolerance", p, low=0.0, strict_low=True))
    if "newton_max_iterations" in tab:
        extra["newton_max_iterations"] = int(r.number(tab, "newton_max_iterations", p, low=1, integer=True))
    if "contact" in tab:
        extra["contact"] = r.choice(tab, "contact", p, ("auto", "nlgs", "block"))
    return Solver(
        time_step=float(r.number(tab, "time_step", p, low=0.0, strict_low=True)),
        theta=float(r.number(tab, "theta", p, low=0.5, high=1.0)),
        nlgs_tolerance=float(r.number(tab, "nlgs_tolerance", p, low=0.0, strict_low=True)),
        nlgs_max_sweeps=int(r.number(tab, "nlgs_max_sweeps", p, low=1, integer=True)),
        relaxation=float(r.number(tab, "relaxation", p, low=0.0, high=1.0, strict_low=True)),
        skin=float(r.number(tab, "skin", p, low=0.0, strict_low=True)),
        **extra,
    )


def _read_output(r: _Reader) -> Output:
    tab = r.table("output")
    p = "output."
    return Output(
        frames=r.choice(tab, "frames", p, ("stages", "none")),
        every_steps=int(r.number(tab, "every_steps", p, low=0, integer=True)),
        checkpoint_every_steps=int(r.number(tab, "checkpoint_every_steps", p, low=1, integer=True)),
    )


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
