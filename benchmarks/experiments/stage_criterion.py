"""Steps per stage against the stage-end test: a scene's whole loading program run with several
settings of its ``[loading]`` table or time steps, against a run with a ten times tighter test.

A stage ends when φ changed by less than ``phi_tolerance`` (relative) between two checks
``check_every`` steps apart and the walls' inertial number is below ``inertial_tolerance``
(compute/run.py). Each variant is the scene folder with some of these keys replaced; reported:
steps per stage, wall seconds, Newton iterations, and the equilibrated φ of every stage with its
difference from the tight run (phi_tolerance and inertial_tolerance divided by 10), the error the
test leaves. One thread; the variants run one after the other. Writes
benchmarks/results/OUTPUT.md.

    python -m studies.mixture_compaction.pre --workdir W --n 144 --kappa 0.5 --mu 0.2 --element T6 \\
        --pressures 0.01 0.03 0.1 0.3 1
    python benchmarks/experiments/stage_criterion.py --scene W/runs/k0.5_mu0.2_s1/scene --check-every 20 10 5 \\
        --output stage_criterion_144
"""

from __future__ import annotations

import os

for _var in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import csv  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
import tomllib  # noqa: E402
from pathlib import Path  # noqa: E402

from pre.scene import copy_scene  # noqa: E402

RESULTS = Path(__file__).resolve().parents[1] / "results"


def run_variant(scene: Path, out: Path) -> dict:
    """Run a scene folder; its stages' steps and end φ (the last history row of each stage)."""
    from compute.errors import SimulationError
    from compute.run import run

    t0 = time.perf_counter()
    try:
        run(scene, out, log=lambda m: None)
        status = "complete"
    except SimulationError as exc:
        status = f"failed: {exc}"
    return {"status": status, "seconds": time.perf_counter() - t0} | stages_of(out)


def stages_of(out: Path) -> dict:
    """Steps per stage, Newton iterations and each stage's end φ (its last history row) of an
    output folder."""
    last: dict[int, dict] = {}
    steps: dict[int, int] = {}
    newton = 0
    for row in csv.DictReader(open(out / "history.csv")):  # a failed run has no summary.json
        stage = int(row["stage"])
        last[stage], steps[stage] = row, steps.get(stage, 0) + 1
        newton += int(row["newton_iterations"])
    return {"steps": [steps[k] for k in sorted(steps)], "newton": newton,
            "phi": [float(last[k]["phi"]) for k in sorted(last)]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", type=Path, required=True, help="a scene folder with a pressure-stage program")
    ap.add_argument("--check-every", type=int, nargs="*", default=[20, 10, 5])
    ap.add_argument("--time-step", type=float, nargs="*", default=[],
                    help="variants with solver.time_step replaced (the stage test unchanged)")
    ap.add_argument("--output", default="stage_criterion")
    a = ap.parse_args()
    value = tomllib.loads((a.scene / "scene.toml").read_text())["loading"]
    variants = {"tight (tolerances / 10)": {"loading.phi_tolerance": value["phi_tolerance"] / 10,
                                            "loading.inertial_tolerance": value["inertial_tolerance"] / 10}}
    variants |= {f"check_every = {c}": {"loading.check_every": c} for c in a.check_every}
    variants |= {f"h = {h:g}": {"solver.time_step": h} for h in a.time_step}
    rows = {}
    with tempfile.TemporaryDirectory() as tmp:
        for i, (name, settings) in enumerate(variants.items()):
            folder = copy_scene(a.scene, Path(tmp) / f"v{i}", settings)
            rows[name] = run_variant(folder, Path(tmp) / f"v{i}_out")
            r = rows[name]
            print(f"{name}: {r['status']}, {sum(r['steps'])} steps {r['steps']}, {r['seconds']:.0f} s", flush=True)
    tight = rows[next(iter(variants))]
    write_table(f"Steps per stage against the stage-end test ({a.scene.parent.name})",
                f"`python benchmarks/experiments/stage_criterion.py --scene {a.scene} --check-every "
                f"{' '.join(map(str, a.check_every))} --time-step {' '.join(map(str, a.time_step))} --output {a.output}`; "
                f"time step h = {tomllib.loads((a.scene / 'scene.toml').read_text())['solver']['time_step']:g} but in the h = variants; the scene's test: φ change below "
                f"{value['phi_tolerance']:g} between checks, inertial number below {value['inertial_tolerance']:g}.",
                "variant", rows, tight, a.output)


def write_table(title: str, how: str, first: str, rows: dict, reference: dict, output: str) -> None:
    """Write benchmarks/results/OUTPUT.md, and print it: a table of the runs ``rows`` ({name:
    run_variant-like dict}) with each one's largest end-φ difference from ``reference``'s; ``how``
    the paragraph under the title, ``first`` the first column's header."""
    lines = [f"# {title}", "", f"{how} |Δφ| = largest difference of a stage's end φ from the tight run's.", "",
             f"| {first} | status | steps per stage | steps | seconds | Newton iterations | end φ per stage | \\|Δφ\\| |",
             "|---|---|---|---|---|---|---|---|"]
    for name, r in rows.items():
        same = len(r["phi"]) == len(reference["phi"])
        dphi = max(abs(p - q) for p, q in zip(r["phi"], reference["phi"])) if same else float("nan")
        lines.append(f"| {name} | {r['status']} | {' '.join(map(str, r['steps']))} | {sum(r['steps'])} | "
                     f"{r['seconds']:.0f} | {r['newton']} | {' '.join(f'{p:.5f}' for p in r['phi'])} | {dphi:.1e} |")
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / f"{output}.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))

if __name__ == "__main__":
    main()
