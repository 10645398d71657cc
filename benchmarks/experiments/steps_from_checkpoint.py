"""Cost of the next steps of a run from its checkpoint, for comparing two versions of compute.

Copies RUN/out (frames left out) to a temporary folder, resumes the run from its checkpoint with
the code of the current directory's checkout (so that a git worktree of another commit can be
measured with this same script), and takes --steps steps of the loading program, one thread.
Prints one JSON line: wall seconds, steps, Newton iterations, cuts, load halvings, contact
sweeps, φ after every step (with --solves, every contact solve of every step: sweeps, error
reached, seconds); --json appends it to a file.

    python -m studies.mixture_compaction.pre --workdir W --n 500 --kappa 1 --mu 0.2 --stages 7
    python -m compute W/runs/k1_mu0.2_s1/scene --out W/runs/k1_mu0.2_s1/out   # stop it in stage 5
    python benchmarks/experiments/steps_from_checkpoint.py --run W/runs/k1_mu0.2_s1 --steps 40 --label after
    (cd WORKTREE && python /path/to/benchmarks/experiments/steps_from_checkpoint.py --run ... --label before)
"""

from __future__ import annotations

import os
import sys

if "--as-cli" not in sys.argv:  # --as-cli: the pools as `python -m compute --threads 1` starts them
    for _var in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
        os.environ[_var] = "1"

import argparse  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

sys.path.append(str(Path(__file__).resolve().parents[1]))  # benchmarks/: the shared helpers
import checkout  # noqa: E402


class Recorded:
    """A contact solver that records (sweeps, error, seconds) of each solve in ``log``; its other
    attributes (tolerance, measure, …) are the solver's."""

    def __init__(self, solver, log: list):
        self.solver, self.log = solver, log

    def __getattr__(self, name):
        return getattr(self.solver, name)

    def solve(self, problem):
        t = time.perf_counter()
        report = self.solver.solve(problem)
        self.log.append((report.iterations, float(f"{report.residual:.3g}"), round(time.perf_counter() - t, 3)))
        return report


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--run", type=Path, required=True, help="a run folder with scene/ and out/ (with a checkpoint)")
    ap.add_argument("--steps", type=int, default=40)
    ap.add_argument("--label", default="")
    ap.add_argument("--contact", help="contact solver instead of the scene's (solver.contact)")
    ap.add_argument("--time-step", type=float, help="time step h instead of the scene's (solver.time_step)")
    ap.add_argument("--screening", type=float, help="solver.contact_screening instead of the scene's")
    ap.add_argument("--tolerance", type=float, help="solver.contact_tolerance instead of the scene's")
    ap.add_argument("--json", type=Path, help="append the result line to this file")
    ap.add_argument("--solves", action="store_true", help="record every contact solve (sweeps, error, seconds)")
    ap.add_argument("--as-cli", action="store_true",
                    help="threads as `python -m compute --threads 1` sets them (compute.threads.configure(1)), "
                         "the BLAS pools left to the checkout, instead of every pool pinned to 1 by the environment")
    a = ap.parse_args()
    sys.path.insert(0, os.getcwd())  # the checkout being measured
    if a.as_cli:
        from compute.threads import configure

        configure(1)
    from compute.stepping import load_control

    commit = checkout.commit()
    with checkout.resumed(a.run) as run:
        if a.contact or a.screening is not None or a.tolerance is not None:
            from dataclasses import replace

            from compute import solvers

            scene = run.scene.solver
            settings = replace(scene, contact=a.contact or scene.contact,
                               contact_screening=scene.contact_screening if a.screening is None else a.screening,
                               contact_tolerance=scene.contact_tolerance if a.tolerance is None else a.tolerance)
            run.stepper.solver = solvers.for_model(settings, run.model)
        if a.time_step:
            run.stepper.h = a.time_step
        solves: list = []
        solver = run.stepper.solver
        if a.solves:
            run.stepper.solver = Recorded(run.stepper.solver, solves)
        st, pressures = run.state, run.scene.loading.pressures
        previous = pressures[st.stage - 1] if st.stage else 0.0
        first = st.step
        result = {"label": a.label, "commit": commit, "contact": type(solver).__name__, "h": run.stepper.h,
                  "screening": run.scene.solver.contact_screening if a.screening is None else a.screening,
                  "tolerance": run.stepper.solver.tolerance,
                  "from_step": first, "stage": st.stage, "newton_iterations": 0, "cuts": 0, "load_halvings": 0,
                  "sweeps": 0, "phi": [], "step_seconds": [], "step_counts": [], "sub_steps": [], **({"solves": []} if a.solves else {})}
        t0 = time.perf_counter()
        try:
            for _ in range(a.steps):
                t = time.perf_counter()
                st, rep, _, halvings = checkout.controlled_step(load_control, run.stepper, st, previous,
                                                                pressures[st.stage], lambda msg: None)
                result["step_seconds"].append(round(time.perf_counter() - t, 3))
                result["newton_iterations"] += rep.newton_iterations
                result["cuts"] += rep.cuts
                result["load_halvings"] += halvings
                result["sweeps"] += rep.sweeps
                result["phi"].append(run.model.phi(st.q))
                result["sub_steps"].append(getattr(rep, "sub_steps", 1))
                result["step_counts"].append((rep.newton_iterations, rep.sweeps))
                if a.solves:
                    result["solves"].append(solves[:])
                    solves.clear()
            result["end"] = "ok"
        except Exception as exc:  # a failed step ends the measurement; it is part of the result
            result["end"] = f"{type(exc).__name__}: {exc}"
        result["seconds"] = round(time.perf_counter() - t0, 2)
        result["steps"] = st.step - first
    checkout.emit(result, a.json)


if __name__ == "__main__":
    main()
