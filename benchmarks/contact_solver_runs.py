"""Whole runs of scenes with different contact solvers, side by side: wall time, where it went,
the work counted, and φ at every stage's end.

Each scene is copied once per ``--contact`` value with ``solver.contact`` set to it (pre's
copy_scene) and run to its end by ``python -m compute``'s code in a process of its own, one
thread (NUMBA_NUM_THREADS=1), ``--parallel`` processes at a time, so that two solvers
measured together share the machine alike. Per run: the wall time of the compute stage,
compute.timing's phase times (the contact solve's share), steps, Newton iterations, contact
iterations (NLGS or block sweeps, MPRGP or interior-point iterations, as history.csv counts
them) and φ at the last step of every stage. Written: benchmarks/results/OUTPUT.md and OUTPUT.csv;
the runs stay in --workdir (a finished run is not run again). The runs are not sent through
studies.dispatch, whose run processes do not report compute.timing's phases.

    python benchmarks/contact_solver_runs.py --scene W/runs/k0.2_mu0_s1/scene --contact nlgs_block mprgp \\
        --workdir /tmp/solver_runs --output frictionless_qp_n1500
"""

from __future__ import annotations

import os

for _var in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import csv  # noqa: E402
import json  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from concurrent.futures import ThreadPoolExecutor  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results"


def run_one(scene: Path, out: Path) -> dict:
    """Run ``scene`` into ``out`` in this process; the wall time and compute.timing's phases."""
    from compute.__main__ import main
    from compute.timing import TIMES

    t0 = time.perf_counter()
    code = main([str(scene), "--out", str(out), "--threads", "1"])
    return {"exit": code, "wall": time.perf_counter() - t0, "phases": dict(TIMES.seconds)}


def counts(out: Path) -> dict:
    """Steps, Newton iterations, contact iterations and φ at each stage's last step (history.csv)."""
    from stage_steps import read_history  # benchmarks/ (this script's folder, first on sys.path)

    h = read_history(out)
    stages = h["stage"].astype(int)
    ends = [int(np.flatnonzero(stages == s)[-1]) for s in np.unique(stages)]
    status = json.loads((out / "summary.json").read_text())["status"] if (out / "summary.json").is_file() else "failed"
    return {"status": status, "steps": int(h.size), "newton": int(h["newton_iterations"].sum()),
            "iterations": int(h["nlgs_sweeps"].sum()), "phi": [float(h["phi"][i]) for i in ends]}


def measured(folder: Path) -> dict:
    """Run folder/scene into folder/out in a process of its own (unless it finished before)."""
    record = folder / "run.json"
    if not record.is_file():
        done = subprocess.run([sys.executable, __file__, "--one", str(folder)], capture_output=True, text=True)
        if done.returncode != 0:
            raise SystemExit(f"{folder}: the run process failed:\n{done.stderr[-2000:]}")
    return {**json.loads(record.read_text()), **counts(folder / "out")}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", type=Path, nargs="+", help="scene folders written by pre")
    ap.add_argument("--contact", nargs="+", help="solver.contact values to compare")
    ap.add_argument("--workdir", type=Path)
    ap.add_argument("--parallel", type=int, default=2)
    ap.add_argument("--output")
    ap.add_argument("--one", type=Path, help=argparse.SUPPRESS)  # internal: run FOLDER/scene, write FOLDER/run.json
    a = ap.parse_args()
    if a.one:
        result = run_one(a.one / "scene", a.one / "out")
        (a.one / "run.json").write_text(json.dumps(result))
        return
    if not (a.scene and a.contact and a.workdir and a.output):
        ap.error("--scene, --contact, --workdir and --output are required")
    from pre.scene import copy_scene

    folders = []
    for scene in a.scene:
        if not (scene / "scene.toml").is_file():
            ap.error(f"--scene {scene}: no scene.toml; give a scene folder written by pre")
        for contact in a.contact:
            folder = a.workdir / f"{scene.parent.name}_{contact}"
            if not (folder / "scene").is_dir():
                copy_scene(scene, folder / "scene", {"solver.contact": contact})
            folders.append((scene.parent.name, contact, folder))
    with ThreadPoolExecutor(a.parallel) as pool:
        results = list(pool.map(lambda f: measured(f[2]), folders))
    write(folders, results, a)


def write(folders, results, a) -> None:
    lines = [f"# Contact solvers over whole runs: {', '.join(a.contact)}", "",
             "`python benchmarks/contact_solver_runs.py --scene " + " ".join(str(s) for s in a.scene)
             + f" --contact {' '.join(a.contact)} --workdir W --parallel {a.parallel} --output {a.output}`", "",
             f"One thread per run, {a.parallel} runs at a time. Contact iterations: sweeps of the Gauss–Seidel "
             "solvers, iterations of the others (history.csv's nlgs_sweeps).", "",
             "| run | contact | status | wall s | contact solve s | steps | Newton iterations | contact iterations "
             "| φ at each stage's end |",
             "|---|---|---|---|---|---|---|---|---|"]
    rows = []
    for (run, contact, _), r in zip(folders, results):
        solve = r["phases"].get("contact solve", float("nan"))
        lines.append(f"| {run} | {contact} | {r['status']} | {r['wall']:.0f} | {solve:.0f} | {r['steps']} | {r['newton']} "
                     f"| {r['iterations']} | {' '.join(f'{p:.4f}' for p in r['phi'])} |")
        rows.append({"run": run, "contact": contact, "status": r["status"], "wall_s": round(r["wall"], 1),
                     "contact_solve_s": round(solve, 1), "steps": r["steps"], "newton_iterations": r["newton"],
                     "contact_iterations": r["iterations"], "phi_stage_ends": " ".join(f"{p:.6f}" for p in r["phi"])})
    (RESULTS / f"{a.output}.md").write_text("\n".join(lines) + "\n")
    with open(RESULTS / f"{a.output}.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    print("\n".join(lines))


if __name__ == "__main__":
    main()
