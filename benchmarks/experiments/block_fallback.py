"""The block Gauss–Seidel fallback of ``nlgs_block`` on the first contact problem of a run where
NLGS hands over to it, sweep by sweep, and as the fallback stops it.

Resumes RUN from its checkpoint (a temporary copy of RUN/out, benchmarks/checkout.py) with the
code of the current directory's checkout, one thread, and takes up to --steps steps of its
loading program. At the --handover-th solve where NLGS stalls (the earlier ones solved as the
run solves them), the problem as the fallback receives it
(NLGS's iterate as its warm start) is solved twice from that same start: by block Gauss–Seidel
one sweep at a time for --sweeps sweeps, printing each sweep's error (natural map, the scene's
measure) and seconds; and by the fallback as ``nlgs_block`` configures it (its stall test
included, in checkouts that have one). Prints one JSON line.

    python benchmarks/experiments/block_fallback.py --run V/v4 --steps 120 --handover 2 --sweeps 230
"""

from __future__ import annotations

import os
import sys

for _var in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import copy  # noqa: E402
import time  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

sys.path.append(str(Path(__file__).resolve().parents[1]))  # benchmarks/: the shared helpers
import checkout  # noqa: E402


class Handover(Exception):
    """Raised by the recording fallback with a copy of the problem it was given."""

    def __init__(self, problem):
        super().__init__("NLGS handed over")
        self.problem = problem


class Catch:
    """Stands in for the block fallback: solves the first ``handover`` - 1 problems it receives
    by it, then raises Handover with the next one."""

    def __init__(self, fallback, handover: int):
        self.fallback, self.left = fallback, handover

    def solve(self, problem):
        self.left -= 1
        if self.left > 0:
            return self.fallback.solve(problem)
        raise Handover(copy.deepcopy(problem))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--run", type=Path, required=True, help="a run folder with scene/ and out/ (with a checkpoint)")
    ap.add_argument("--steps", type=int, default=100, help="steps to take at most before a handover")
    ap.add_argument("--handover", type=int, default=1, help="which handover to trace (1: the first)")
    ap.add_argument("--sweeps", type=int, default=200, help="block sweeps to trace one by one")
    a = ap.parse_args()
    sys.path.insert(0, os.getcwd())  # the checkout being measured
    from compute.solvers.nlgs_then import NLGSThen
    from compute.stepping import load_control

    result = {"commit": checkout.commit(), "run": str(a.run)}
    with checkout.resumed(a.run) as run:
        solver = run.stepper.solver
        if not isinstance(solver, NLGSThen):
            raise SystemExit(f"{a.run}: the run's contact solver is {type(solver).__name__}, not nlgs_block's")
        fallback = solver.fallbacks[0]
        run.stepper.solver = replace(solver, fallbacks=(Catch(fallback, a.handover),))
        st, pressures = run.state, run.scene.loading.pressures
        result["from_step"] = st.step
        problem = None
        for _ in range(a.steps):
            try:
                st, *_ = checkout.controlled_step(load_control, run.stepper, st,
                                                  pressures[st.stage - 1] if st.stage else 0.0,
                                                  pressures[st.stage], lambda msg: None)
            except Handover as h:
                problem = h.problem
                break
        if problem is None:
            result["handover"] = None
            checkout.emit(result, None)
            return
        result["handover_in_step"] = st.step + 1
        result["contacts"] = int(problem.mu.shape[0])
        one = replace(fallback, max_sweeps=1)
        if hasattr(one, "stall_window"):
            one = replace(one, stall_window=0)
        traced, trace = copy.deepcopy(problem), []
        for sweep in range(1, a.sweeps + 1):
            t = time.perf_counter()
            rep = one.solve(traced)
            trace.append((sweep, float(f"{rep.residual:.4g}"), round(time.perf_counter() - t, 2)))
            print(*trace[-1], flush=True)
            if rep.residual <= one.tolerance:
                break
        result["trace"] = trace
        t = time.perf_counter()
        rep = fallback.solve(problem)
        result["fallback"] = {"sweeps": rep.iterations, "error": rep.residual,
                              "seconds": round(time.perf_counter() - t, 1), "solver": repr(fallback)}
    checkout.emit(result, None)


if __name__ == "__main__":
    main()
