"""The stage-end test over a sliding window against the test every check_every steps: one
scene's loading program run by two checkouts side by side, and by this one with a ten times
tighter test (the reference for the equilibrated φ).

Each run is ``python -m compute SCENE --out OUT --threads 1`` in its checkout's folder, one after
the other. Reported per run: steps per stage, wall seconds, Newton iterations, the end φ of each
stage and its largest difference from the tight run's. Writes benchmarks/results/OUTPUT.md.

    git worktree add /tmp/before <commit before the sliding test>
    python -m studies.mixture_compaction.pre --workdir W --n 144 --kappa 0.5 --mu 0.2 --element T6 \\
        --pressures 0.01 0.03 0.1 0.3 1
    python benchmarks/experiments/stage_window.py --scene W/runs/k0.5_mu0.2_s1/scene --before /tmp/before \\
        --output stage_window_144
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

from stage_criterion import stages_of, write_table

HERE = Path(__file__).resolve().parents[2]


def run_in(checkout: Path, scene: Path, out: Path) -> dict:
    env = dict(os.environ, NUMBA_NUM_THREADS="1", OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    t0 = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "compute", str(scene), "--out", str(out), "--threads", "1"],
                          cwd=checkout, env=env, capture_output=True, text=True)
    status = "complete" if (out / "COMPLETE").is_file() else "incomplete" if (out / "INCOMPLETE").is_file() \
        else f"failed ({done.returncode})"
    return {"status": status, "seconds": time.perf_counter() - t0} | stages_of(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", type=Path, required=True, help="a scene folder with a pressure-stage program")
    ap.add_argument("--before", type=Path, required=True, help="a checkout of the code before the change")
    ap.add_argument("--output", default="stage_window")
    a = ap.parse_args()
    sys.path.insert(0, str(HERE))
    from pre.scene import copy_scene

    scene = a.scene.resolve()
    loading = tomllib.loads((scene / "scene.toml").read_text())["loading"]
    rows = {}
    with tempfile.TemporaryDirectory() as tmp:
        tight = copy_scene(scene, Path(tmp) / "tight", {"loading.phi_tolerance": loading["phi_tolerance"] / 10,
                                                        "loading.inertial_tolerance": loading["inertial_tolerance"] / 10})
        for name, checkout, folder in (("before (test every check_every steps)", a.before.resolve(), scene),
                                       ("after (sliding window)", HERE, scene),
                                       ("tight (after, tolerances / 10)", HERE, tight)):
            rows[name] = r = run_in(checkout, folder, Path(tmp) / f"out{len(rows)}")
            print(f"{name}: {r['status']}, {sum(r['steps'])} steps {r['steps']}, {r['seconds']:.0f} s", flush=True)
    write_table(f"Stage-end test: sliding window against checks every check_every steps ({scene.parent.name})",
                f"`python benchmarks/experiments/stage_window.py --scene {a.scene} --before {a.before} --output {a.output}`; "
                f"check_every = {loading['check_every']}, phi_tolerance = {loading['phi_tolerance']:g}, inertial_tolerance = "
                f"{loading['inertial_tolerance']:g}, force_tolerance = {loading['force_tolerance']:g}. One thread per run, "
                "the runs one after the other.", "run", rows, rows["tight (after, tolerances / 10)"], a.output)

if __name__ == "__main__":
    main()
