"""The energy budget of a run, step by step: does the discrete dynamics only lose energy?

Runs SCENE's loading program from its start (a temporary output folder, one thread) with the
code of the current directory's checkout and, after every step, records

    E = kinetic + strain energy of the soft bodies + P × box area

(the enthalpy of the packing under the walls' pressure P, which frictionless contacts with no
restitution, backward Euler and the damped walls can only lower while P is constant), the soft
bodies' rigid spin (kinetic energy of the rotation fitted to each body's nodes, its angular
momentum over its moment of inertia) and the deepest overlap of any contact at the step's start.
Prints, per stage and per sixth of it: steps, the change of E, the fraction of steps where E
rose and the largest rise, mean kinetic and spin energy, median start-of-step overlap. Why: with the segment–disk
rows linearised at the step's start, a 30-disk frictionless mixture gained energy at half its
steps, its soft disks spinning, and never came to rest (compute.contact.end_of_step).

    python -m studies.mixture_compaction.pre --workdir W
    python benchmarks/experiments/step_energy.py W/runs/k0.5_mu0_s1/scene --stages 3
    (cd WORKTREE && PYTHONPATH=. python /path/to/benchmarks/experiments/step_energy.py ...)
"""

from __future__ import annotations

import os

for _var in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402


class _Enough(Exception):
    """The asked stages are done."""


def spin_energy(model, q: np.ndarray, v: np.ndarray) -> float:
    """Kinetic energy of the soft bodies' rigid rotations, ½ L² / I per body about its centroid."""
    e = 0.0
    for g in model.soft:
        x = g.nodes(q)
        c = g.rotation_momenta(x)  # (B, 2n): c·v is the angular momentum about the centroid
        arm = x - g.batch.centroids(x)[:, None, :]
        inertia = np.sum(c * np.stack([-arm[..., 1], arm[..., 0]], axis=2).reshape(g.B, -1), axis=1)
        momentum = np.sum(c * g.nodes(v).reshape(g.B, -1), axis=1)
        e += float(np.sum(0.5 * momentum**2 / inertia))
    return e


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene", type=Path)
    ap.add_argument("--stages", type=int, default=3, help="stages of the program to run")
    ap.add_argument("--max-steps", type=int, default=1500, help="steps per stage at most")
    a = ap.parse_args()
    sys.path.insert(0, os.getcwd())  # the checkout being measured
    from compute.run import Run

    records: list[dict] = []
    with tempfile.TemporaryDirectory() as tmp:
        run = Run(a.scene, Path(tmp) / "out", log=lambda msg: None)
        m, take = run.model, run.stepper.step

        def step(state, pressure, wall_speed=0.0):
            new, rep = take(state, pressure, wall_speed)
            b = m.bounds(new.q)
            strain = sum(float(np.sum(g.batch.strain_energy(g.nodes(new.q)))) for g in m.soft)
            records.append({"stage": state.stage, "P": pressure, "ke": m.kinetic_energy(new.v),
                            "E": m.kinetic_energy(new.v) + strain + pressure * (b[1] - b[0]) * (b[3] - b[2]),
                            "spin": spin_energy(m, new.q, new.v), "overlap": rep.max_penetration})
            if state.stage >= a.stages or state.stage_steps >= a.max_steps:
                raise _Enough
            return new, rep

        run.stepper.step = step
        try:
            run.execute()
        except _Enough:
            pass
    print("| stage | steps | ΔE | steps where E rose | largest rise | kinetic | spin | overlap at start (median) |")
    print("|---|---|---|---|---|---|---|---|")
    for stage in sorted({r["stage"] for r in records}):
        rs = [r for r in records if r["stage"] == stage]
        w = max(1, len(rs) // 6)
        for lo in range(0, len(rs) - 1, w):
            part = rs[lo:lo + w + 1]
            E = np.array([r["E"] for r in part])
            print(f"| {stage} | {lo + 1}-{lo + len(part) - 1} | {E[-1] - E[0]:+.1e} | {np.mean(np.diff(E) > 0):.2f} | "
                  f"{max(np.diff(E).max(), 0.0):.0e} | "
                  f"{np.mean([r['ke'] for r in part]):.1e} | {np.mean([r['spin'] for r in part]):.1e} | "
                  f"{np.median([r['overlap'] for r in part]):.1e} |")


if __name__ == "__main__":
    main()
