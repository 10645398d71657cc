"""Threads of the parallel kernels: numba's threading layer, OpenMP's wait policy and the number
of threads, on a quiet machine and next to a busy process.

Runs ``python -m compute`` on one scene (default: the 144-disk κ = 0.5, μ = 0.2, T3 × 92 mixture
that benchmarks/soft_step_cost.py prepares) in each configuration, alone and beside a competing
CPU-bound process (one busy Python loop, as another job on a shared 2-core machine), rounds
alternating over the configurations; wall time of the whole command, after an untimed warm-up.

    python benchmarks/threads.py --scene SCENE --workdir W [--repeats 3]

Groups smaller than compute.threads.MIN_BODIES_PER_THREAD per thread run on one thread whatever
the configuration, so the scene must hold enough soft bodies for the configurations to differ
(e.g. a κ = 1 mixture of 500 disks).

Writes benchmarks/results/threads.md (keeping the section of benchmarks/freed_cores.py: a run
switched from 1 to 2 threads while it runs by OUT/threads).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

RESULTS = Path(__file__).resolve().parent / "results"
FREED_CORES = "## A run given a freed core while it runs"
CONFIGS = {  # name: (environment, --threads)
    "1 thread": ({}, 1),
    "2 threads, omp, OMP_WAIT_POLICY=active": ({"NUMBA_THREADING_LAYER": "omp", "OMP_WAIT_POLICY": "active"}, 2),
    "2 threads, omp, OMP_WAIT_POLICY=passive": ({"NUMBA_THREADING_LAYER": "omp", "OMP_WAIT_POLICY": "passive"}, 2),
    "2 threads, omp, libgomp's default spin (GOMP_SPINCOUNT=300000)": ({"NUMBA_THREADING_LAYER": "omp",
                                                                        "GOMP_SPINCOUNT": "300000"}, 2),
    "2 threads, omp, short spin (GOMP_SPINCOUNT=10000)": ({"NUMBA_THREADING_LAYER": "omp",
                                                          "GOMP_SPINCOUNT": "10000"}, 2),
    "2 threads, workqueue": ({"NUMBA_THREADING_LAYER": "workqueue"}, 2),
}


def run(scene: Path, out: Path, env_extra: dict, threads: int) -> float:
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_NUM_THREADS", "OMP_WAIT_POLICY", "GOMP_SPINCOUNT")}
    env.update(env_extra)
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "compute", str(scene), "--out", str(out), "--threads", str(threads)],
                   env=env, check=True, capture_output=True)
    return time.perf_counter() - t0


LAUNCH = """
import time, numba, numpy as np
@numba.njit(parallel=True)
def f(a):
    s = 0.0
    for i in numba.prange(a.shape[0]):
        s += a[i]
    return s
a = np.ones(1000)
f(a)
t = time.perf_counter()
for _ in range(5000):
    f(a)
print((time.perf_counter() - t) / 5000 * 1e6)
"""


def launch_costs() -> dict:
    """Microseconds per launch of a tiny parallel kernel: 2 passive or spinning threads, or 1."""
    out = {}
    for name, env_extra in (("2 threads, passive", {"OMP_WAIT_POLICY": "passive", "NUMBA_NUM_THREADS": "2"}),
                            ("2 threads, libgomp's default spin", {"NUMBA_NUM_THREADS": "2"}),
                            ("1 thread", {"NUMBA_NUM_THREADS": "1"})):
        env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_NUM_THREADS", "OMP_WAIT_POLICY", "GOMP_SPINCOUNT")}
        env.update(env_extra)
        res = subprocess.run([sys.executable, "-c", LAUNCH], env=env, check=True, capture_output=True, text=True)
        out[name] = float(res.stdout.strip().splitlines()[-1])
    return out


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--scene", type=Path, required=True)
    p.add_argument("--workdir", type=Path, required=True)
    p.add_argument("--repeats", type=int, default=3)
    a = p.parse_args(argv)
    times = {(name, busy): [] for name in CONFIGS for busy in (False, True)}
    for rep in range(a.repeats + 1):
        for busy in (False, True):
            hog = subprocess.Popen([sys.executable, "-c", "while True: pass"]) if busy else None
            try:
                for name, (env, threads) in CONFIGS.items():
                    t = run(a.scene, a.workdir / "out", env, threads)
                    if rep:
                        times[(name, busy)].append(t)
            finally:
                if hog:
                    hog.kill()
                    hog.wait()
    lines = ["# Threads of the parallel kernels", "",
             f"`python benchmarks/threads.py --scene {a.scene} --repeats {a.repeats}`: wall time (s) of "
             "`python -m compute` on the scene, alone and beside one busy process (2-core machine); "
             "median of the repeats, all values in brackets.", "",
             "| configuration | alone | beside a busy process |", "|---|---|---|"]
    for name in CONFIGS:
        cells = [f"{np.median(times[(name, b)]):.2f} ({', '.join(f'{t:.2f}' for t in times[(name, b)])})"
                 for b in (False, True)]
        lines.append(f"| {name} | {cells[0]} | {cells[1]} |")
    lines += ["", "Cost of one launch of a tiny parallel kernel (the price a parallel kernel pays before it "
              "gains anything; compute.threads gives a group one thread per MIN_BODIES_PER_THREAD bodies):", "",
              "| pool | µs per launch |", "|---|---|"]
    lines += [f"| {name} | {us:.1f} |" for name, us in launch_costs().items()]
    RESULTS.mkdir(exist_ok=True)
    old = (RESULTS / "threads.md").read_text() if (RESULTS / "threads.md").is_file() else ""
    kept = old[old.index(FREED_CORES):] if FREED_CORES in old else ""  # benchmarks/freed_cores.py's section
    (RESULTS / "threads.md").write_text("\n".join(lines) + "\n" + ("\n" + kept if kept else ""))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
