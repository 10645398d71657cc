"""The numerical error of one mixture run: the same run with a halved time step, a ten times
tighter contact tolerance, a ten times tighter stage-end test, a four times finer soft mesh and
walls three times more damped (a slower approach to each stage's equilibrium: the terminal
inertial number / 3), against the run as the study sets it; and what coarser settings would
save and cost (a doubled time step, ten times looser Newton and contact tolerances, a three
times looser stage-end test).

Each variant is the run's scene with one setting changed (the mesh variant is the study's
jammed rigid scene with the same soft disks, chosen by the same seed, meshed with
``--mesh-factor`` times the elements). The variants are dispatched as a study's runs are
(studies.dispatch: ``--workers`` at a time, one thread each at first, resumed if killed, wall
times in WORKDIR/dispatch.jsonl); post's measures then give φ, Z and P at every equilibrated
stage, and the Platzer law is fitted to φ(P) as the study does. Written:
benchmarks/results/OUTPUT.md (the table, and the largest difference of each variant from the
base run), OUTPUT.csv (every stage of every variant) and OUTPUT_fits.md (the study table's
fitted numbers per variant: ξ, α, φ_max, P₀, the laws' errors; ``--fits-only`` writes it again
from OUTPUT.csv alone). Outputs stay in --workdir, one folder
per variant whatever ``--variants`` picks, so that runs are shared between outputs.

    W=studies/mixture_compaction/results/n1500_t3
    python benchmarks/numerical_error.py --run $W/runs/k0.2_mu0.2_s1 --rigid $W/rigid/mu0.2_s1/scene \\
        --kappa 0.2 --seed 1 --workdir runs/numerical_error --output numerical_error_n1500_k0.2_mu0.2
"""

from __future__ import annotations

import argparse
import csv
import tomllib
from pathlib import Path

import numpy as np

RESULTS = Path(__file__).resolve().parent / "results"


def variants(scene: Path, mesh_factor: int) -> dict[str, dict]:
    """Name -> overrides ("table.key" -> value) of the scene's settings; "mesh" is built apart."""
    from compute.schema import migrate

    params = migrate(scene / "scene.toml", tomllib.loads((scene / "scene.toml").read_text()))
    s, load = params["solver"], params["loading"]
    return {"base": {},
            "h / 2": {"solver.time_step": s["time_step"] / 2},
            "contact tolerance / 10": {"solver.contact_tolerance": s["contact_tolerance"] / 10},
            "stage test / 10": {"loading.phi_tolerance": load["phi_tolerance"] / 10,
                                "loading.inertial_tolerance": load["inertial_tolerance"] / 10},
            f"mesh × {mesh_factor}": {},
            "wall damping / 3": {"walls.damping_inertial_number": params["walls"]["damping_inertial_number"] / 3},
            "h × 2": {"solver.time_step": s["time_step"] * 2},
            "Newton tolerance × 10": {"solver.newton_tolerance": s["newton_tolerance"] * 10},
            "contact tolerance × 10": {"solver.contact_tolerance": s["contact_tolerance"] * 10},
            "stage test × 3": {"loading.phi_tolerance": load["phi_tolerance"] * 3,
                               "loading.inertial_tolerance": load["inertial_tolerance"] * 3}}


def mesh_scene(run_scene: Path, rigid_scene: Path, folder: Path, kappa: float, seed: int, factor: int) -> Path:
    """The run's scene with its soft disks meshed ``factor`` times finer: the study's
    pre.mixture.mixture_scene on the same jammed packing, with the same seed (the same soft
    disks) and the run's own settings."""
    from compute.scene import read_scene
    from compute.schema import migrate
    from pre.mixture import mixture_scene

    scene = read_scene(run_scene)
    soft = scene.deformable
    raw = migrate(run_scene / "scene.toml", tomllib.loads((run_scene / "scene.toml").read_text()))
    material = next(m for m in scene.materials.values() if m.kind != "rigid")
    _, mask = mixture_scene(rigid_scene, folder, kappa, float(scene.friction.max()), np.random.default_rng(seed),
                            element=soft[0].element, n_elements=factor * len(soft[0].cells),
                            young=material.young, poisson=material.poisson, parameters=raw)
    if set(np.flatnonzero(mask)) != {d.body for d in soft}:
        raise SystemExit(f"{folder}: κ {kappa} and seed {seed} do not give the run's soft disks; give the study's")
    return folder


def stages(out: Path) -> dict:
    """φ, Z, P/E at the equilibrated frames (post's measures) and steps, Newton iterations,
    contact sweeps (the history's, all sub-steps of a step counted)."""
    import json

    from post.table import measure_output
    from stage_steps import read_history  # benchmarks/ (this script's folder, first on sys.path)

    rows = [r for r in measure_output(out) if r["equilibrated"]]
    summary = json.loads((out / "summary.json").read_text()) if (out / "summary.json").is_file() else {}
    history = read_history(out) if (out / "history.csv").is_file() else None  # a failed run's steps too
    return {"status": summary.get("status", "failed"), "steps": 0 if history is None else int(history.size),
            "newton": 0 if history is None else int(history["newton_iterations"].sum()),
            "sweeps": 0 if history is None else int(history["nlgs_sweeps"].sum()),
            "P": np.array([r["pressure_applied"] for r in rows]), "phi": np.array([r["phi"] for r in rows]),
            "Z": np.array([r["Z"] for r in rows])}


# the study table's fitted numbers (post.compaction.SEED_KEYS, in that order), as headed in the table
FITTED_HEADS = ("ξ", "α", "φ_max Eq. 5", "φ_max Platzer", "P₀/E", "Eq. 5 err φ rms", "Platzer err φ rms")


def write_fits(curves: Path, b: float, output: str) -> str:
    """OUTPUT_fits.md: per variant of the table ``curves`` (OUTPUT.csv), the fitted numbers
    (post.compaction.run_fits, with Eq. 2's ``b``) and their differences from the base run; the
    largest difference over the refining variants (finer h, contact tolerance, stage test, mesh,
    slower walls) is the numerical error of each number. φ₀, Z₀ are read at each variant's first
    stage (the error of the loaded stages alone), Eq. 5 with the variant's own ξ, α."""
    from post.compaction import SEED_KEYS as FITTED, run_fits

    with open(curves, newline="") as fh:
        rows = list(csv.DictReader(fh))
    names = list(dict.fromkeys(r["variant"] for r in rows))
    numbers = {}
    for name in names:
        mine = [r for r in rows if r["variant"] == name]
        P, phi, Z = (np.array([float(r[k]) for r in mine]) for k in ("P_over_E", "phi", "Z"))
        numbers[name] = run_fits(phi, P, Z, phi[0], Z[0], b)
    base = numbers["base"]
    refining = [n for n in names if " / " in n or n.startswith("mesh")]  # the finer or slower settings
    fmt = {"xi": "{:.2f}", "alpha": "{:.3f}", "platzer_P0": "{:.3f}"}
    lines = [f"# The fitted numbers of {curves.name}'s variants", "",
             f"`python benchmarks/numerical_error.py --fits-only --output {output} --b {b:g}`", "",
             "φ₀, Z₀ at each variant's first stage; Eq. 5 with b = " + f"{b:g}" + " and the variant's own ξ, α. "
             "Each cell: the value, and its difference from the base run.", "",
             "| variant | " + " | ".join(FITTED_HEADS) + " |", "|---|" + "---|" * len(FITTED)]
    for name in names:
        cells = []
        for k in FITTED:
            v = numbers[name][k]
            text = fmt.get(k, "{:.4f}").format(v)
            cells.append(text if name == "base" else f"{text} ({v - base[k]:+.1e})")
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    largest = {k: max(abs(numbers[n][k] - base[k]) for n in refining) for k in FITTED}
    lines += ["", f"Largest difference over the refining variants ({', '.join(refining)}): "
              + ", ".join(f"{h} {largest[k]:.1e}" for h, k in zip(FITTED_HEADS, FITTED)) + "."]
    text = "\n".join(lines) + "\n"
    (RESULTS / f"{output}_fits.md").write_text(text)
    return text


def main() -> None:
    from pre.scene import copy_scene
    from studies.dispatch import RunSpec, dispatch, run_times

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--run", type=Path, help="a study run folder (scene/ inside)")
    ap.add_argument("--rigid", type=Path, help="the study's jammed rigid scene of that run")
    ap.add_argument("--kappa", type=float, help="the study's κ of that run (as asked)")
    ap.add_argument("--seed", type=int, help="the study's seed of that run")
    ap.add_argument("--mesh-factor", type=int, default=4)
    ap.add_argument("--workdir", type=Path)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--output", required=True)
    ap.add_argument("--variants", nargs="+", metavar="NAME",
                    help="run and report only these variants (and the base run): names as in the table, "
                         "e.g. 'h × 2' (default: all)")
    ap.add_argument("--fits-only", action="store_true",
                    help="only write OUTPUT_fits.md from an existing OUTPUT.csv (no run)")
    ap.add_argument("--b", type=float, default=None,
                    help="Eq. 2's b for the fitted numbers (default: the single particle's, T3 × 92)")
    a = ap.parse_args()
    b = a.b if a.b is not None else _study_b()
    if a.fits_only:
        if not (RESULTS / f"{a.output}.csv").is_file():
            ap.error(f"--fits-only: {RESULTS / a.output}.csv not found (the variants' table that a run writes)")
        print(write_fits(RESULTS / f"{a.output}.csv", b, a.output))
        return
    missing = [f"--{k.replace('_', '-')}" for k in ("run", "rigid", "kappa", "seed", "workdir") if getattr(a, k) is None]
    if missing:
        ap.error(f"the arguments {', '.join(missing)} are required (all but --output with --fits-only)")
    scene = a.run / "scene"
    for folder, option in ((scene, "--run RUN: RUN/scene"), (a.rigid, "--rigid")):
        if not (folder / "scene.toml").is_file():
            ap.error(f"{folder}: no scene.toml; {option} must be a scene folder written by pre")
    every = variants(scene, a.mesh_factor)
    unknown = set(a.variants or ()) - set(every)
    if unknown:
        ap.error(f"--variants: no variant {', '.join(sorted(unknown))}; the variants are {', '.join(every)}")
    folders = {}
    for i, (name, overrides) in enumerate(every.items()):
        if a.variants and name != "base" and name not in a.variants:
            continue
        folder = a.workdir / f"v{i}" / "scene"  # the index in the full list: a folder keeps its variant
        if not folder.is_dir():
            folder.parent.mkdir(parents=True, exist_ok=True)
            if name.startswith("mesh"):
                mesh_scene(scene, a.rigid, folder, a.kappa, a.seed, a.mesh_factor)
            else:
                copy_scene(scene, folder, overrides)
        folders[name] = folder
    log_file = a.workdir / "dispatch.jsonl"
    dispatch([RunSpec(name, f, f.parent / "out") for name, f in folders.items()], n_workers=a.workers,
             log_file=log_file, progress=False)
    seconds = run_times(log_file)
    results = {name: stages(f.parent / "out") for name, f in folders.items()}
    write(results, seconds, a)
    print(write_fits(RESULTS / f"{a.output}.csv", b, a.output))


def _study_b() -> float:
    """Eq. 2's b of the study's soft disk (T3 × 92) from the single particle's fits per mesh."""
    from post.compaction import law_from_file

    return law_from_file(RESULTS.parents[1] / "studies/single_particle/results/refinement_fits.csv", "T3", 92).b


def write(results: dict, seconds: dict, a) -> None:
    from post.fits import fit_platzer

    base = results["base"]
    lines = [f"# Numerical error of {a.run.name} ({a.run.parent.parent.name})", "",
             f"`python benchmarks/numerical_error.py --run {a.run} --rigid {a.rigid} --kappa {a.kappa:g} --seed {a.seed} "
             f"--mesh-factor {a.mesh_factor} --workdir W --output {a.output}"
             + "".join(f" --variants '{v}'" if i == 0 else f" '{v}'" for i, v in enumerate(a.variants or ())) + "`", "",
             "Per variant: status, steps, Newton iterations, contact sweeps, wall seconds (one thread at first, "
             f"{a.workers} variants at a time), φ at every equilibrated stage, Platzer φ_max and P₀ fitted "
             "from the first stage's φ, and the largest |Δφ| and |ΔZ| over the stages against the base run.", "",
             "| variant | status | steps | Newton iterations | contact sweeps | s | φ per stage | Platzer φ_max, P₀/E "
             "| max \\|Δφ\\| | max \\|ΔZ\\| |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    rows = []
    for name, r in results.items():
        fit = fit_platzer(r["phi"], r["P"], r["phi"][0]) if len(r["phi"]) >= 3 else None
        same = len(r["phi"]) == len(base["phi"])
        dphi = np.abs(r["phi"] - base["phi"]).max() if same else np.nan
        dz = np.abs(r["Z"] - base["Z"]).max() if same else np.nan
        platzer = f"{fit.params['phi_max']:.4f}, {fit.params['P0']:.3f}" if fit else "–"
        lines.append(f"| {name} | {r['status']} | {r['steps']} | {r['newton']} | {r['sweeps']} | {seconds.get(name, float('nan')):.0f} | "
                     f"{' '.join(f'{p:.4f}' for p in r['phi'])} | {platzer} | {dphi:.1e} | {dz:.2f} |")
        rows += [{"variant": name, "P_over_E": p, "phi": f, "Z": z} for p, f, z in zip(r["P"], r["phi"], r["Z"])]
    (RESULTS / a.output).parent.mkdir(parents=True, exist_ok=True)
    (RESULTS / f"{a.output}.md").write_text("\n".join(lines) + "\n")
    with open(RESULTS / f"{a.output}.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, ["variant", "P_over_E", "phi", "Z"])
        w.writeheader()
        w.writerows(rows)
    print("\n".join(lines))


if __name__ == "__main__":
    main()
