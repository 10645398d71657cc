"""A run given a freed core while it runs: ``--threads 1`` against the same run switched to 2
threads by ``OUT/threads`` (what studies.dispatch writes once a study's other runs have ended),
and against ``--threads 2`` from the start.

The scene must hold enough soft bodies for compute.threads.for_bodies to give its group 2 threads
(at least 2 x MIN_BODIES_PER_THREAD = 400), e.g.

    python -m studies.mixture_compaction.pre --workdir W --n 800 --kappa 1 --mu 0.2 --element T3 --pressures 0.01
    python benchmarks/freed_cores.py --scene W/runs/<run>/scene --workdir W2 --steps 60 --repeats 2

The scene is copied with ``loading.max_steps_per_stage = --steps`` (the run ends INCOMPLETE after
that many steps); every run has NUMBA_NUM_THREADS = 2 (the pool a dispatched run starts with on a
2-core machine). "switched by OUT/threads" writes the file once the run's first step is done
(history.csv or progress.json appears), as the dispatcher would mid-run. Wall time of the whole
command (start-up included, the same in every configuration), rounds alternating over the
configurations after an untimed warm-up; the load of the machine (other jobs) is recorded.

Writes its section of benchmarks/results/threads.md (replacing an earlier one).
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

RESULTS = Path(__file__).resolve().parent / "results" / "threads.md"
HEADING = "## A run given a freed core while it runs (OUT/threads)"
CONFIGS = ("--threads 1", "--threads 1, switched to 2 by OUT/threads after step 1", "--threads 2")


def prepare(scene: Path, workdir: Path, steps: int) -> Path:
    import tomllib

    import tomli_w

    copy = workdir / f"scene_{steps}"
    if copy.exists():
        shutil.rmtree(copy)
    shutil.copytree(scene, copy)
    params = tomllib.loads((copy / "scene.toml").read_text())
    params["loading"]["max_steps_per_stage"] = steps
    params["output"]["every_steps"] = 0
    (copy / "scene.toml").write_text(tomli_w.dumps(params))
    return copy


def run(scene: Path, out: Path, config: str) -> float:
    if out.exists():
        shutil.rmtree(out)
    env = {k: v for k, v in os.environ.items() if k not in ("OMP_WAIT_POLICY", "GOMP_SPINCOUNT")}
    env["NUMBA_NUM_THREADS"] = "2"
    threads = "2" if config == CONFIGS[2] else "1"
    t0 = time.perf_counter()
    child = subprocess.Popen([sys.executable, "-m", "compute", str(scene), "--out", str(out), "--threads", threads],
                             env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    if config == CONFIGS[1]:
        from compute import files

        while child.poll() is None and not (out / "progress.json").exists():
            time.sleep(0.01)
        if child.poll() is None:
            files.write_text(out / "threads", "2\n")
    _, err = child.communicate()
    if child.returncode != 0:
        raise SystemExit(f"compute failed ({child.returncode}): {err[-2000:]}")
    if config == CONFIGS[1] and "threads: 1 -> 2" not in err:
        raise SystemExit("the run did not pick up OUT/threads:\n" + err[-2000:])
    return time.perf_counter() - t0


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--scene", type=Path, required=True)
    p.add_argument("--workdir", type=Path, required=True)
    p.add_argument("--steps", type=int, default=20)
    p.add_argument("--repeats", type=int, default=2)
    a = p.parse_args(argv)
    a.workdir.mkdir(parents=True, exist_ok=True)
    scene = prepare(a.scene, a.workdir, a.steps)
    one_step = prepare(a.scene, a.workdir, 1)  # start-up and first step: subtracted for seconds per step
    from compute.scene import read_scene

    sc = read_scene(scene)
    n_bodies, n_soft = len(sc.radius), len(sc.radius) - len(sc.rigid_ids)
    times = {c: [] for c in CONFIGS}
    starts = []
    loads = [os.getloadavg()[0]]
    for rep in range(a.repeats + 1):
        t = run(one_step, a.workdir / "out", CONFIGS[0])
        if rep:
            starts.append(t)
        for config in CONFIGS:
            t = run(scene, a.workdir / "out", config)
            if rep:
                times[config].append(t)
        loads.append(os.getloadavg()[0])
    base, start = np.median(times[CONFIGS[0]]), np.median(starts)
    per_step = {c: (np.median(times[c]) - start) / (a.steps - 1) for c in CONFIGS}
    lines = [HEADING, "",
             f"`python benchmarks/freed_cores.py --scene {a.scene} --steps {a.steps} --repeats {a.repeats}` "
             f"({n_bodies} bodies, {n_soft} soft): "
             f"wall time (s) of `python -m compute` for {a.steps} steps, NUMBA_NUM_THREADS = 2; median of the "
             "repeats, all values in brackets. 1-minute load average of the machine during the rounds: "
             + ", ".join(f"{x:.2f}" for x in loads) + f". Seconds per step: (wall time - that of a 1-step run, "
             f"{start:.2f} s ({', '.join(f'{t:.2f}' for t in starts)})) / {a.steps - 1}.", "",
             "| configuration | wall time (s) | against --threads 1 | s per step | against --threads 1 |",
             "|---|---|---|---|---|"]
    for c in CONFIGS:
        m = np.median(times[c])
        lines.append(f"| {c} | {m:.2f} ({', '.join(f'{t:.2f}' for t in times[c])}) | {m / base:.2f} | "
                     f"{per_step[c]:.3f} | {per_step[c] / per_step[CONFIGS[0]]:.2f} |")
    section = "\n".join(lines) + "\n"
    text = RESULTS.read_text() if RESULTS.is_file() else ""
    if HEADING in text:
        text = text[:text.index(HEADING)]
    RESULTS.write_text(text.rstrip("\n") + "\n\n" + section)
    print(section)


if __name__ == "__main__":
    main()
