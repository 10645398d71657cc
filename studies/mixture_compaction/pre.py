"""Stage 1 of the mixture compaction study (Cárdenas-Barrantes et al. 2021): N polydisperse rigid
disks jammed by the compute stage (pre.jamming); then, for each mixture ratio κ, a fraction κ of
the particle volume replaced by neo-Hookean disks at the same positions and sizes (pre.mixture),
written as DIR/runs/<name>/scene with the loading program: pressure stages P/E log-spaced from
--p-min to --p-max, each equilibrated.

Preparation (--preparation):
- shared (the default): per seed, one packing jammed with friction --jamming-mu (default 0:
  the small default's calibration; the 1500-disk study gives 0.2) and one κ replacement (the
  same soft disks: the choice depends on the packing and the seed only), compacted with each μ
  of the study. The paper's φ₀ for μ = 0 and 0.2 agree within 0.002 at every κ, which jamming
  each μ with its own friction does not give: its two frictions start from one prepared sample
  (study README, "Preparation").
- per-friction: each μ jams its own packing with friction μ.

With --relax rigid, a run whose μ is below the jamming friction starts from the shared
packing jammed again with rigid disks at its μ (pre.jamming.relaxed_rigid_scene, once per μ and
seed, in DIR/rigid/mu<jamming μ>_s<seed>_relaxed_mu<μ>/): with less friction the packing flows to a
denser jammed state at the first pressure, which rigid disks compute in a fraction of the time
the finite-element disks take; the soft disks' strain there is of the order of P/E = 1e-3. This
is the default. With --relax none that flow is the first stage of the run itself. Either way φ₀
and Z₀ are the prepared (shared) sample's (study README, "Preparation").

The prepared sample's φ₀ and Z₀, written per run in study.json ("prepared"), are measured as post
measures a frame (post.measures): φ on the mixture scene (rigid disks π r², soft disks by their
element areas, the box of its walls); the Z columns on the jamming run's last frame (the same
positions; rattlers by the jamming friction's rule, post.measures.default_min_contacts), also
kept with the jamming record so that --add reusing it has them.

Writes DIR/study.json (the runs and their parameters), DIR/rigid/mu<μ>_s<seed>/ (the jamming
runs and the jammed rigid scenes; *_relaxed_mu<μ>/ the relaxed ones) and
DIR/runs/k<κ>_mu<μ>_s<seed>/scene. Reduced units: mean
diameter 1, density 1, E = 1 (soft disks; rigid ones have E = infinity).

With --add, the (κ, μ, seed) runs not yet in DIR/study.json are added to it: the study's runs
keep their scenes and outputs (some may be running), a jammed packing of the same (μ, seed) is
reused (a relaxed one too), and the study's settings (N, elements, pressures, preparation, --relax,
--set) must be the same.
Why: a large study is run over several sessions, one or two runs at a time, and analysed as one
study. A study.json without "preparation" (written before it existed) is per-friction.
"""

if not __package__:  # run as a file (python studies/X/stage.py): studies/entry.py
    import pathlib, sys; sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2]))
    from studies.entry import run_as_file; run_as_file(__file__)

import argparse
import json
import shutil
import sys
import time
from pathlib import Path

import numpy as np

# The small default: the whole study (4 kappa x 2 mu, one seed) to P/E = 1 in 7 stages (the
# program of the 1500-disk runs) in minutes on 2 cores, on the smallest box whose prepared phi0
# lies within 0.01 of the paper's (README.md, "Results of the small default"). Its packing is
# jammed without friction: a calibration of the small box, whose walls loosen it; the 1500-disk
# study jams with the study's friction, --jamming-mu 0.2 (README.md, "Preparation").
DEFAULTS = {"n": 225, "kappa": [0.2, 0.5, 0.8, 1.0], "mu": [0.0, 0.2], "seeds": [1],
            "p_min": 1e-3, "p_max": 1.0, "stages": 7, "preparation": "shared", "jamming_mu": 0.0,
            "relax": "rigid"}
# what a study.json written before a setting existed holds (--add compares with it)
LEGACY_SETTINGS = {"preparation": "per-friction", "relax": "none"}
# the rigid jamming runs of the preparation: jammed at P = 1 in units of rho <d>^2/t^2 (rigid
# disks: P only sets the time scale)
JAMMING_OVERRIDES = {"solver.time_step": 0.1}


def run_name(kappa: float, mu: float, seed: int) -> str:
    """The folder name of a run under DIR/runs."""
    return f"k{kappa:g}_mu{mu:g}_s{seed}"


def parse_set(items: list[str]) -> dict:
    """--set table.key=value items -> {"table.key": value} (value parsed as JSON, else a string)."""
    out = {}
    for item in items:
        key, sep, text = item.partition("=")
        if not sep or key.count(".") != 1:
            raise SystemExit(f"--set {item!r}: expected table.key=value, e.g. solver.time_step=0.5")
        try:
            out[key] = json.loads(text)
        except json.JSONDecodeError:
            out[key] = text
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--workdir", required=True, help="study folder (DIR)")
    p.add_argument("--n", type=int, default=DEFAULTS["n"], help=f"number of disks (default {DEFAULTS['n']}; paper 1500)")
    p.add_argument("--kappa", type=float, nargs="+", default=DEFAULTS["kappa"],
                   help="mixture ratios: fraction of the particle volume made deformable (default 0.2 0.5 0.8 1)")
    p.add_argument("--mu", type=float, nargs="+", default=DEFAULTS["mu"],
                   help="inter-particle friction coefficients (default 0 0.2); walls are frictionless")
    p.add_argument("--preparation", choices=("shared", "per-friction"), default=DEFAULTS["preparation"],
                   help="shared (default): per seed one packing jammed with --jamming-mu and one choice of soft "
                        "disks, compacted with every mu; per-friction: each mu jams its own packing")
    p.add_argument("--jamming-mu", type=float, default=None,
                   help=f"shared preparation: friction of the rigid disks while they are jammed "
                        f"(default {DEFAULTS['jamming_mu']})")
    p.add_argument("--relax", choices=("rigid", "none"), default=None,
                   help="shared preparation: runs with less friction than --jamming-mu start from the packing "
                        "jammed again with rigid disks at their friction (rigid, the default) or from the shared "
                        "packing itself (none; module docstring)")
    p.add_argument("--seeds", type=int, nargs="+", default=DEFAULTS["seeds"], help="random seeds (default 1)")
    p.add_argument("--p-min", type=float, default=DEFAULTS["p_min"], help="first P/E (default 1e-3)")
    p.add_argument("--p-max", type=float, default=DEFAULTS["p_max"], help=f"last P/E (default {DEFAULTS['p_max']})")
    p.add_argument("--stages", type=int, default=DEFAULTS["stages"],
                   help=f"number of log-spaced pressure stages (default {DEFAULTS['stages']})")
    p.add_argument("--pressures", type=float, nargs="+", default=None, help="explicit P/E stages (overrides the above)")
    p.add_argument("--element", choices=("T3", "T6"), default="T3", help="soft-disk elements (default T3, as the paper)")
    p.add_argument("--elements", type=int, default=92, help="triangles per soft disk (default 92, as the paper)")
    p.add_argument("--volumetric", choices=("standard", "mean_dilatation"), default="standard",
                   help="volumetric term of the soft disks (default standard; mean_dilatation: T6 only, "
                        "it does not reach P/E = 1, study README)")
    p.add_argument("--set", action="append", default=[], metavar="TABLE.KEY=VALUE",
                   help="override a scene parameter of the runs, e.g. --set solver.time_step=0.5 (repeatable)")
    p.add_argument("--force", action="store_true",
                   help="delete existing run outputs (DIR/runs/*/out) instead of refusing to overwrite them")
    p.add_argument("--add", action="store_true",
                   help="add the runs not yet in DIR/study.json, keeping its runs and their outputs (module docstring)")
    a = p.parse_args(argv)
    if a.add and a.force:
        p.error("--add keeps the study's outputs, --force deletes them: give one of them")
    if a.preparation == "per-friction" and (a.jamming_mu is not None or a.relax is not None):
        p.error("--jamming-mu and --relax set the shared preparation; per-friction jams each mu with itself")
    relax = (a.relax or DEFAULTS["relax"]) if a.preparation == "shared" else "none"
    shared_mu = (DEFAULTS["jamming_mu"] if a.jamming_mu is None else a.jamming_mu) if a.preparation == "shared" else None

    from pre.jamming import jammed_rigid_scene, relaxed_rigid_scene
    from post.frames import read_frames_table
    from pre.mixture import compaction_parameters, mixture_scene
    from pre.scene import neo_hookean_material

    w = Path(a.workdir)
    if any(k < 0 or k > 1 for k in a.kappa) or any(m < 0 for m in [*a.mu, shared_mu or 0.0]) or a.n < 2:
        p.error("expected 0 <= kappa <= 1, mu >= 0, jamming mu >= 0 and n >= 2")
    pressures = a.pressures or list(np.geomspace(a.p_min, a.p_max, a.stages))
    if any(x <= 0 for x in pressures) or any(np.diff(pressures) <= 0):
        p.error(f"pressures: expected increasing positive P/E, got {pressures}")
    overrides = parse_set(a.set)
    settings = {"study": "mixture_compaction", "n": a.n, "element": a.element, "elements": a.elements,
                "volumetric": neo_hookean_material(a.element, a.volumetric)["volumetric"],
                "pressures_over_E": [float(x) for x in pressures], "young": 1.0, "poisson": 0.495,
                "overrides": overrides, "preparation": a.preparation, "jamming_mu": shared_mu, "relax": relax}
    if a.add:
        before = _study_to_extend(p, w / "study.json", settings)
    else:
        before = {"jamming": [], "relaxed": [], "runs": [], "pre_seconds": 0.0}
        existing = sorted((w / "runs").glob("*/out"))
        if existing and not a.force:
            p.error(f"{w / 'runs'} already holds run outputs ({existing[0]} ...): use --force to start the study "
                    f"again, or --add to add runs to it")
        for out in existing:
            shutil.rmtree(out)
        (w / "post").exists() and a.force and shutil.rmtree(w / "post")
    kept = {r["name"] for r in before["runs"]}
    jammed = {(j["mu"], j["seed"]): j for j in before["jamming"]}
    relaxed = {(j["mu"], j["seed"]): j for j in before.get("relaxed", [])}
    # φ₀ of each prepared sample (κ, seed, jamming μ), measured once: its frictions' scenes hold
    # the same soft disks, translated where relaxed, whose areas differ in the last bit
    sample_phi = {(r["kappa"], r["seed"], r.get("jamming_mu")): r["prepared"]["phi"]
                  for r in before["runs"] if r.get("prepared")}

    runs, jams, relaxations = [], [], []
    t_start = time.perf_counter()
    for mu in a.mu:
        mu_jam = mu if shared_mu is None else shared_mu
        for seed in a.seeds:
            if all(run_name(kappa, mu, seed) in kept for kappa in a.kappa):
                continue
            if (mu_jam, seed) in jammed:
                rigid_scene = w / jammed[(mu_jam, seed)]["scene"]
                print(f"jammed mu = {mu_jam:g}, seed {seed}: {rigid_scene} (the study's)", flush=True)
            else:
                t0 = time.perf_counter()
                rigid_dir = w / "rigid" / f"mu{mu_jam:g}_s{seed}"
                # jammed at P = 1 in units of rho <d>^2/t^2 (rigid disks: P only sets the time scale)
                rigid_scene = jammed_rigid_scene(rigid_dir, a.n, mu_jam, seed, [1.0],
                                                 overrides=JAMMING_OVERRIDES, log=lambda msg: None)
                equilibrated = read_frames_table(rigid_dir / "jamming" / "out")[-1].equilibrated
                jammed[(mu_jam, seed)] = {"mu": mu_jam, "seed": seed, "scene": str(rigid_scene.relative_to(w)),
                                          "equilibrated": equilibrated, "seconds": round(time.perf_counter() - t0, 1),
                                          "measures": jammed_measures(rigid_dir / "jamming" / "out", mu_jam)}
                jams.append(jammed[(mu_jam, seed)])
                print(f"jammed mu = {mu_jam:g}, seed {seed}: {rigid_scene} ({time.perf_counter() - t0:.1f} s"
                      f"{'' if equilibrated else ', NOT equilibrated within the step budget'})", flush=True)
            jam = jammed[(mu_jam, seed)]
            if "measures" not in jam:  # a jamming recorded before its measures were
                jam["measures"] = jammed_measures((w / jam["scene"]).parent / "jamming" / "out", mu_jam)
            from compute.scene import read_scene

            prepared_bounds = bounds = read_scene(rigid_scene).walls.bounds
            if relax == "rigid" and mu < mu_jam:
                if (mu, seed) not in relaxed:
                    t0 = time.perf_counter()
                    relaxed_dir = w / "rigid" / f"mu{mu_jam:g}_s{seed}_relaxed_mu{mu:g}"
                    scene = relaxed_rigid_scene(rigid_scene, relaxed_dir, mu, overrides=JAMMING_OVERRIDES,
                                                log=lambda msg: None)
                    record = read_frames_table(relaxed_dir / "jamming" / "out")[-1]
                    relaxed[(mu, seed)] = {"mu": mu, "seed": seed, "from_mu": mu_jam,
                                           "scene": str(scene.relative_to(w)), "equilibrated": record.equilibrated,
                                           "seconds": round(time.perf_counter() - t0, 1)}
                    relaxations.append(relaxed[(mu, seed)])
                    print(f"relaxed at mu = {mu:g}, seed {seed}: {scene} ({time.perf_counter() - t0:.1f} s"
                          f"{'' if record.equilibrated else ', NOT equilibrated within the step budget'})", flush=True)
                rigid_scene = w / relaxed[(mu, seed)]["scene"]
                bounds = read_scene(rigid_scene).walls.bounds
            params = compaction_parameters(bounds, mu, pressures, overrides, element=a.element, bodies=a.n)
            for kappa in a.kappa:
                name = run_name(kappa, mu, seed)
                if name in kept:
                    print(f"  {name}: already in the study, kept", flush=True)
                    continue
                folder, soft = mixture_scene(rigid_scene, w / "runs" / name / "scene", kappa, mu,
                                             np.random.default_rng(seed), element=a.element,
                                             n_elements=a.elements, volumetric=a.volumetric, parameters=params)
                radii = np.asarray(read_scene(folder).radius)
                actual = float(np.sum(radii[soft] ** 2) / np.sum(radii**2))
                sample = (kappa, seed, mu_jam)
                if sample not in sample_phi and jam["measures"] is not None:
                    sample_phi[sample] = prepared_phi(folder, prepared_bounds)
                prepared = None if jam["measures"] is None else {
                    "phi": sample_phi[sample], **{k: v for k, v in jam["measures"].items() if k.startswith("Z")}}
                runs.append({"name": name, "kappa": kappa, "mu": mu, "jamming_mu": mu_jam, "seed": seed,
                             "n_soft": int(soft.sum()),
                             "kappa_actual": round(actual, 6), "scene": str(folder.relative_to(w)),
                             "out": str((w / "runs" / name / "out").relative_to(w)), "prepared": prepared})
                print(f"  {name}: {int(soft.sum())} of {a.n} disks deformable (volume fraction {actual:.3f})"
                      + (f", prepared phi0 = {prepared['phi']:.4f}, Z0 = {prepared['Z']:.3f}" if prepared else ""),
                      flush=True)
    study = {**settings, "jamming": before["jamming"] + jams, "relaxed": before.get("relaxed", []) + relaxations,
             "runs": before["runs"] + runs,
             "pre_seconds": round(before["pre_seconds"] + time.perf_counter() - t_start, 1)}
    (w / "study.json").write_text(json.dumps(study, indent=1) + "\n")
    print(f"{len(runs)} scenes written; study description {w / 'study.json'} ({len(study['runs'])} runs)")
    return 0


def prepared_phi(scene_folder: Path, bounds) -> float:
    """φ of a scene's particles as post measures it on a frame (post.measures): rigid disks π r²,
    soft disks by their element areas (a T3 disk is its inscribed boundary polygon, less than
    π r²), over the box ``bounds`` (xmin, xmax, ymin, ymax) of the prepared packing (a relaxed
    run's scene has a smaller one). Why: the runs' φ is measured so, and φ₀ must be on the same
    scale."""
    from compute.scene import read_scene
    from post import measures

    scene = read_scene(scene_folder)
    rigid = np.zeros(scene.n_bodies, dtype=bool)
    rigid[scene.rigid_ids] = True
    offsets = np.cumsum([0] + [len(d.points) for d in scene.deformable])
    points = np.concatenate([d.points for d in scene.deformable] + [np.empty((0, 2))])
    meshes = [(d.cells + offset, np.full(len(d.cells), d.body)) for d, offset in zip(scene.deformable, offsets)]
    areas = measures.particle_areas(np.asarray(scene.radius), rigid, points, meshes)
    return measures.packing_fraction(areas, measures.box_area(np.asarray(bounds)))


def jammed_measures(out: Path, friction: float, threshold: float = 1e-9) -> dict | None:
    """The last frame of the jamming run ``out`` measured by post (post.table.measure_frame,
    rattlers by the rule of the jamming ``friction``, active contacts fn > ``threshold`` x mean fn,
    post.py's default): {"frame", "phi" (the rigid packing's), "min_contacts", and every Z column}.
    None, with a note, when the frame is not there (a study carried without its frames)."""
    from post.errors import OutputError
    from post.frames import read_frame, read_frames_table
    from post.measures import default_min_contacts
    from post.table import measure_frame

    try:
        record = read_frames_table(out)[-1]
        row = measure_frame(read_frame(out, record), default_min_contacts(friction), threshold)
    except OutputError as exc:
        print(f"no prepared phi0, Z0: the jamming frame is not readable ({exc})", flush=True)
        return None
    return {"frame": record.frame, "phi": row["phi"], "min_contacts": default_min_contacts(friction),
            **{k: v for k, v in row.items() if k.startswith("Z")}}


def _study_to_extend(p, path: Path, settings: dict) -> dict:
    """The study of ``path`` (--add), after checking that its settings are ``settings`` (a field
    missing from it holds its LEGACY_SETTINGS value)."""
    if not path.is_file():
        p.error(f"--add: {path} not found (run pre.py without --add first)")
    study = json.loads(path.read_text())
    for key, value in settings.items():
        if study.get(key, LEGACY_SETTINGS.get(key)) != value:
            p.error(f"--add: {path}: field '{key}' is {study.get(key, LEGACY_SETTINGS.get(key))!r}, expected "
                    f"{value!r} as given here (the runs of one study share their settings)")
    return study


if __name__ == "__main__":
    sys.exit(main())
