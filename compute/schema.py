"""The scene file's schema: every table and key of ``scene.toml`` once, with type, unit, range,
default and a one-line doc.

compute's reader (:mod:`compute.scene`) validates from it, pre (:mod:`pre.scene`) builds and
checks parameters from it, and the key tables of docs/FORMATS.md are generated from it
(``python -m compute.schema docs/FORMATS.md`` rewrites them; a test checks they are current).

Ranges. Every number is finite. Magnitudes that set a scale (lengths, density, moduli, masses,
pressures, time, velocities) lie within ``[1e-12, 1e12]`` (signed values within ±1e12): a step
multiplies at most four of them (e.g. h² E / (ρ L²)), which then stays within 1e±48, far from
the overflow and underflow of double precision (1e±308) and from denormals, so round-off stays
relative. Tolerances lie in (0, 1); counts are integers in ``[1, 1e9]`` (0 allowed where 0
means "none").

Versions. ``schema_version`` is the layout's version; a file of an older version is migrated on
read (:func:`migrate`: the keys renamed since, ``RENAMED``), so that a scene, or a run's copy of
it, written before a change still runs and resumes. A key's old name in a file of the current
version is an error naming the new one. Version 2 renamed ``solver.nlgs_tolerance`` to
``solver.contact_tolerance``: it governs every contact solver and the Newton loop's contact test,
not NLGS alone.
"""

from __future__ import annotations

import difflib
import math
from dataclasses import dataclass

from compute.errors import InputError, SceneError

SCHEMA_VERSION = 2
# version -> {(table, old name): new name}: the keys that version renamed (migrate)
RENAMED = {2: {("solver", "nlgs_tolerance"): "contact_tolerance"}}
SCALE = 1e12  # bound of every magnitude (module docstring)
PRESSURE_OVER_YOUNG = 5.0  # largest P/E of a soft material the elements handle (compute.scene)
TINY = 1e-12  # smallest positive scale
COUNT = 10**9  # largest count
REQUIRED = object()


@dataclass(frozen=True)
class Key:
    """One key of a table: ``type`` is "float", "int", "bool", "str", "floats" (a list of
    floats, ``length`` of them if given) or "strs" (a non-empty list of strings). A number lies in
    [low, high] (``low`` excluded when ``open_low``); a string is one of ``options`` if given.
    ``when`` = (key, value): the key is required when that key of the same table (or of the
    context, e.g. walls.control for [loading]) has that value, and takes its default (it may
    still be given, and is then checked) otherwise."""

    name: str
    type: str
    doc: str
    unit: str = ""
    low: float | None = None
    high: float | None = None
    open_low: bool = False
    options: tuple[str, ...] = ()
    default: object = REQUIRED
    length: int | None = None
    when: tuple[str, str] | None = None

    @property
    def required(self) -> bool:
        return self.default is REQUIRED

    def range_text(self) -> str:
        if self.options:
            return " \\| ".join(f'"{o}"' for o in self.options)
        if self.low is None and self.high is None:
            return ""
        lo = "-∞" if self.low is None else _num(self.low)
        hi = "∞" if self.high is None else _num(self.high)
        return f"{'(' if self.open_low else '['}{lo}, {hi}]"


def _num(x: float) -> str:
    return f"{x:.10g}" if isinstance(x, float) else str(x)


def _positive(name, doc, unit="", **kw) -> Key:
    return Key(name, "float", doc, unit, low=TINY, high=SCALE, **kw)


def _count(name, doc, low=1, **kw) -> Key:
    return Key(name, "int", doc, low=low, high=COUNT, **kw)


def _tolerance(name, doc, low=0.0, **kw) -> Key:
    return Key(name, "float", doc, low=low, high=1.0, open_low=True, **kw)


TOP = (Key("schema_version", "int", "version of this file layout (an older one is migrated on read: compute/schema.py)",
           low=1, high=SCHEMA_VERSION),)

BODIES = (
    Key("file", "str", "the bodies file, relative to the scene folder and inside it (python -m compute "
        "--bodies-outside-scene: anywhere)"),
    Key("materials", "strs", "material names; the bodies file's cell_data 'material' indexes this list"),
)

RIGID = (
    Key("kind", "str", "the material model", options=("rigid",)),
    _positive("density", "mass per unit area", "mass / length²"),
    Key("fixed", "bool", "a body that never moves (supports, obstacles)", default=False),
)

NEO_HOOKEAN = (
    Key("kind", "str", "the material model", options=("neo_hookean",)),
    _positive("density", "mass per unit area", "mass / length²"),
    _positive("young", "Young's modulus E", "pressure"),
    Key("poisson", "float", "Poisson's ratio ν (plane strain; the displacement elements lock above 0.499999: the "
        "single particle fails at 0.4999999)", low=-1.0, high=0.499999, open_low=True),
    Key("element", "str", "finite element", options=("T3", "T6")),
    Key("volumetric", "str", "volumetric integration (T3 elements: standard only)",
        options=("standard", "mean_dilatation")),
)

INTERACTION = (
    Key("between", "strs", "two material names (an unordered pair, each pair once)", length=2),
    Key("law", "str", "contact law", options=("coulomb", "frictionless")),
    Key("friction", "float", "Coulomb coefficient μ (0 allowed)", low=0.0, high=10.0, when=("law", "coulomb"),
        default=0.0),
)

WALLS = (
    *(Key(k, "float", f"{k} of the box", "length", low=-SCALE, high=SCALE) for k in ("xmin", "xmax", "ymin", "ymax")),
    _positive("mass", "mass of each wall (a numerical device in quasi-statics)", "mass"),
    Key("control", "str", "walls pushed by P × current length, or moved at a given speed",
        options=("pressure", "velocity")),
    Key("damping_inertial_number", "float", "wall damping whose terminal speed gives this inertial number (0: none)",
        low=0.0, high=1.0, default=0.0),
    Key("damping_ratio", "float", "wall damping at least this fraction of the critical damping of the "
        "packing's breathing mode, from its bulk modulus extrapolated from the last stage ends (0: none)",
        low=0.0, high=10.0, default=0.0),
    Key("friction", "float", "walls are frictionless", low=0.0, high=0.0, default=0.0),
)

LOADING = (
    Key("pressures", "floats", "one equilibrated stage per pressure", "pressure", low=TINY, high=SCALE,
        when=("control", "pressure"), default=[]),
    Key("velocity", "float", "inward wall speed", "length / time", low=-SCALE, high=SCALE,
        when=("control", "velocity"), default=0.0),
    _positive("duration", "duration of the velocity stage", "time", when=("control", "velocity"), default=0.0),
    _tolerance("phi_tolerance", "relative change of φ over the last check_every steps that ends a stage"),
    _tolerance("inertial_tolerance", "inertial number I = |ε̇| ⟨d⟩ √(ρ/P) below which a stage may end"),
    Key("force_tolerance", "float", "|contact force − P L| / (P L) on every wall that ends a stage (0: no check)",
        low=0.0, high=1.0, default=0.0),
    _count("check_every", "steps of the sliding window of the stage-end test (tested after every step)"),
    _count("max_steps_per_stage", "a stage ends INCOMPLETE after this many steps"),
    _count("stall_steps", "a stage that makes no progress for this many steps (its contact error above "
           "contact_tolerance and not halving, φ and the walls not moving by phi_tolerance) ends the run "
           "INCOMPLETE (compute/stall.py; 0: never)", low=0, default=10000),
    Key("gravity", "floats", "gravity [gx, gy]", "length / time²", low=-SCALE, high=SCALE, length=2),
)

SOLVER = (
    _positive("time_step", "time step h", "time"),
    Key("theta", "float", "θ of the θ-method (1/2: trapezoidal, 1: backward Euler)", low=0.5, high=1.0),
    _tolerance("contact_tolerance", "contact solve (every solver of contact) and the Newton loop's contact test: the "
               "error of contact_error at which it stops (schema_version 1: nlgs_tolerance)", low=1e-15),
    Key("contact_error", "str", "the contact solve's error (compute/contact/residual.py): impulse |f| / |r|, the "
        "velocity error relative to the velocities the impulses make over the packing (velocity), or at the worst "
        "contact (velocity_max)", options=("impulse", "velocity", "velocity_max"), default="impulse"),
    Key("penetration_bound", "float", "contact solve: also no predicted overlap at the end of a step above this, in "
        "mean diameters (0: no bound)", low=0.0, high=1.0, default=0.0),
    _count("nlgs_max_sweeps", "sweeps of either contact solver"),
    Key("relaxation", "float", "NLGS relaxation", low=0.0, high=1.0, open_low=True),
    Key("skin", "float", "broad-phase skin, in mean diameters", low=0.0, high=10.0, open_low=True),
    _tolerance("newton_tolerance", "Newton loop: position correction, in mean diameters", low=1e-15, default=1e-8),
    Key("newton_max_iterations", "int", "Newton iterations per step attempt", low=1, high=1000, default=20),
    Key("contact", "str", "contact solver (auto: without soft bodies nlgs_ip up to 500 movable disks, nlgs above; "
        "block for one soft body alone, mprgp for soft bodies among more than 100 movable bodies and no friction, else "
        "nlgs_block; interior_point: all contacts together, compute/solvers/interior_point.py; nlgs_ip: NLGS, "
        "the interior point where NLGS stalls, compute/solvers/nlgs_then.py; cone_point: De Saxcé shift fixed point "
        "over monotone cone LCPs, for jammed frictional rigid packings, compute/solvers/cone_point.py; mprgp: frictionless "
        "contact as a bound-constrained quadratic program, projected conjugate gradients, compute/solvers/mprgp.py)",
        options=("auto", "nlgs", "block", "nlgs_block", "interior_point", "nlgs_ip", "cone_point", "mprgp"),
        default="auto"),
    Key("rigid_soft_rows", "str", "rigid disks against soft boundaries: kept off the soft nodes, or off the nodes "
        "and the boundary segments between them (tried with T3; with T6 the half-edges under pressed disks "
        "oscillate and stages may not end: benchmarks/experiments/README.md)", options=("nodes", "nodes_and_segments"),
        default="nodes"),
    Key("hold_rotation", "bool", "hold each soft body's angular momentum about its centroid at zero (a torque "
        "multiplier): removes the rigid rotation that frictionless contacts leave free and that pressure makes "
        "unstable (compute/bodies/soft.py); not for scenes where soft bodies should turn", default=False),
    Key("mass_scaling", "float", "soft bodies' inertia in a pressure stage P: max(1, mass_scaling · P h² / (ρ ⟨d⟩²)) "
        "times their material's (0: none); keeps their Newton matrices positive definite where pressure makes their "
        "tangent indefinite; equilibria do not depend on it, the path between them does (compute/bodies/soft.py)",
        low=0.0, high=1e6, default=0.0),
    Key("contact_screening", "float", "solve each contact problem on the contacts that hold an impulse or "
        "approach within this fraction of the fastest free approach, adding those left out that close, until "
        "none does: the same solution from fewer rows (0: every row; compute/solvers/screened.py)",
        low=0.0, high=1.0, default=0.0),
    Key("step", "str", "step strategy (compute/stepping/strategies.py): fixed_point, the Newton loop around a "
        "complete contact solve, for any scene; active_set, a semismooth Newton with the contact conditions "
        "inside the iteration, for one soft body with hold_rotation, no friction and no movable rigid disk; auto: "
        "active_set where it applies, else fixed_point (docs/ARCHITECTURE.md)",
        options=("auto", "fixed_point", "active_set"), default="auto"),
)

OUTPUT = (
    Key("frames", "str", "a frame at each equilibrated stage, or none", options=("stages", "none")),
    _count("every_steps", "plus a frame every n steps (0: none)", low=0),
    _count("checkpoint_every_steps", "steps between two checkpoints"),
)

SETTINGS = {"walls": WALLS, "loading": LOADING, "solver": SOLVER, "output": OUTPUT}
MATERIALS = {"rigid": RIGID, "neo_hookean": NEO_HOOKEAN}
TABLES = {"bodies": BODIES, **SETTINGS}  # plus [materials.NAME] and [[interactions]]


def table_of(key: str) -> str:
    """The settings table (walls, loading, solver, output) that holds ``key``; keys are unique
    across them."""
    for table, keys in SETTINGS.items():
        if any(k.name == key for k in keys):
            return table
    raise KeyError(unknown_key(key, [k.name for keys in SETTINGS.values() for k in keys]))


def validate(file, prefix: str, table, keys: tuple[Key, ...], context: dict | None = None,
             extra: tuple[str, ...] = ()) -> dict:
    """The values of ``table`` (a dict from TOML) checked against ``keys``, with the defaults of
    absent optional keys; ``prefix`` is the table's dotted name in messages ("solver.").

    Raises :class:`SceneError` on an unknown key (with the closest known names), a missing
    required key, a wrong type (booleans are not numbers), a non-finite number, a value out of
    its range. ``extra``: further names accepted (checked by the caller)."""
    if not isinstance(table, dict):
        raise SceneError(file, prefix.rstrip(".") or "<file>", "a table", table)
    names = [k.name for k in keys]
    for name in table:
        if name not in names and name not in extra:
            raise SceneError(file, prefix + name, unknown_key(name, names + list(extra)))
    out = {}
    for k in keys:
        if k.name not in table:
            if k.when is None:
                needed = k.required
            else:
                needed = {**(context or {}), **table}.get(k.when[0]) == k.when[1]
            if needed:
                raise SceneError(file, prefix + k.name, f"{_type_text(k)} ({k.doc}) (missing)")
            out[k.name] = None if k.required else k.default
            continue
        out[k.name] = check(file, prefix + k.name, table[k.name], k)
    return out


def check(file, field: str, value, k: Key):
    """``value`` checked against ``k``; returns it as a Python float / int / str / bool / list."""
    if k.type in ("floats", "strs"):
        if not isinstance(value, list) or (k.length is not None and len(value) != k.length) \
                or (k.length is None and k.type == "strs" and not value):
            raise SceneError(file, field, _type_text(k), value)
        item = Key(k.name, k.type[:-1], k.doc, k.unit, k.low, k.high, k.open_low, k.options)
        return [check(file, f"{field}[{i}]", v, item) for i, v in enumerate(value)]
    if k.type == "bool":
        if not isinstance(value, bool):
            raise SceneError(file, field, "true or false", value)
        return value
    if k.type == "str":
        if not isinstance(value, str) or (k.options and value not in k.options):
            raise SceneError(file, field, _type_text(k), value)
        return value
    integer = k.type == "int"
    if isinstance(value, bool) or not isinstance(value, int if integer else (int, float)) \
            or not math.isfinite(value):
        raise SceneError(file, field, _type_text(k), value)
    low_bad = k.low is not None and (value <= k.low if k.open_low else value < k.low)
    if low_bad or (k.high is not None and value > k.high):
        raise SceneError(file, field, f"{_type_text(k)} in {k.range_text()}", value)
    return int(value) if integer else float(value)


def _type_text(k: Key) -> str:
    if k.type == "floats":
        return f"a list of {k.length or 'one or more'} finite numbers" + (f" in {k.range_text()}" if k.low is not None else "")
    if k.type == "strs":
        return f"a list of {k.length or 'one or more'} strings"
    if k.options:
        return "one of " + ", ".join(repr(o) for o in k.options)
    return {"float": "a finite number", "int": "an integer", "str": "a string", "bool": "true or false"}[k.type]


def migrate(file, data: dict, error: type[InputError] = SceneError) -> dict:
    """The parameters ``data`` (as read from ``file``) in the current version's layout: those of
    a file of an older ``schema_version`` with its keys renamed since (``RENAMED``), ``data``
    itself when it is current (or its version is not one: :func:`validate` says so). A key of an
    old file already under its new name raises ``error``."""
    version = data.get("schema_version") if isinstance(data, dict) else None
    if isinstance(version, bool) or not isinstance(version, int) or not 1 <= version < SCHEMA_VERSION:
        return data
    out = dict(data)
    for step in range(version + 1, SCHEMA_VERSION + 1):
        for (table, old), new in RENAMED.get(step, {}).items():
            tab = out.get(table)
            if not isinstance(tab, dict):
                continue
            if new in tab:
                raise error(file, f"{table}.{new}", f"{old}, its name in a schema_version {version} file "
                            f"(or schema_version = {SCHEMA_VERSION})")
            if old in tab:
                out[table] = {(new if k == old else k): v for k, v in tab.items()}
    out["schema_version"] = SCHEMA_VERSION
    return out


def renamed(name: str) -> tuple[str, int] | None:
    """(current name, version that renamed it) of ``name`` ("key" or "table.key") if it is a
    key's old name, else None."""
    for version, renames in RENAMED.items():
        for (table, old), new in renames.items():
            if name in (old, f"{table}.{old}"):
                return (new if name == old else f"{table}.{new}"), version
    return None


def unknown_key(name: str, known: list[str]) -> str:
    """What an error on the unknown key ``name`` expects: a known key, the closest ones first; for
    a key's old name, its new name."""
    if renamed(name) is not None:
        new, version = renamed(name)
        return f"{new} (unknown key '{name}': renamed {new} in schema_version {version})"
    close = difflib.get_close_matches(name, known, n=1, cutoff=0.6)
    hint = f"; did you mean {close[0]}?" if close else ""
    return f"a known key (unknown key '{name}'{hint}; known: {', '.join(known)})"


# --- documentation ------------------------------------------------------------------------------
BEGIN, END = "<!-- schema:begin (generated by python -m compute.schema) -->", "<!-- schema:end -->"


def markdown() -> str:
    """The key tables of docs/FORMATS.md."""
    sections = [("(top level)", TOP), ("[bodies]", BODIES), ("[materials.NAME], kind = \"rigid\"", RIGID),
                ("[materials.NAME], kind = \"neo_hookean\"", NEO_HOOKEAN), ("[[interactions]]", INTERACTION),
                *((f"[{t}]", keys) for t, keys in SETTINGS.items())]
    lines = []
    for title, keys in sections:
        lines += [f"**{title}**", "", "| key | type | unit | range | default | meaning |", "|---|---|---|---|---|---|"]
        for k in keys:
            default = "required" if k.required else repr(k.default).replace("'", '"').lower()
            if k.when:
                default = f"required if {k.when[0]} = \"{k.when[1]}\", else {default}"
            doc = k.doc.replace("|", "\\|")
            lines.append(f"| `{k.name}` | {k.type} | {k.unit} | {k.range_text()} | {default} | {doc} |")
        lines.append("")
    return "\n".join(lines)


def _write_docs(path: str) -> None:
    from pathlib import Path

    doc = Path(path)
    text = doc.read_text()
    head, _, rest = text.partition(BEGIN)
    _, _, tail = rest.partition(END)
    doc.write_text(f"{head}{BEGIN}\n\n{markdown()}\n{END}{tail}")


if __name__ == "__main__":
    import sys

    _write_docs(sys.argv[1] if len(sys.argv) > 1 else "docs/FORMATS.md")
