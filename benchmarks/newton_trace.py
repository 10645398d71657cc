"""Why the steps of a soft scene need many Newton iterations or fail: every step attempt's
sequence of position corrections, traced while a scene runs (or resumes).

For each attempt that takes more than ``--longer`` Newton iterations or fails, one line: the step,
its sub-step length h, the iterations and, per iteration, the largest position correction
h θ |Δv|_∞ over the soft bodies, how many bodies were above the Newton tolerance and how many
of those had a stabilised Newton matrix (NewtonMatrices level > 0: the exact M̂ = M + h²θ² K_t
was not positive definite, the body fell back to M̂ without its volumetric geometric stiffness
or with a mass-proportional shift, compute/bodies/soft_matrix.py); then the failure's message.
At the end: attempts, failures, and the level-0 factorisations by their number of negative
pivots (the inertia of the exact M̂).

The trace wraps three functions of the compute stage for the run's duration (the step control's
attempt, SoftBodies.settle, SymbolicLDL.factorize); nothing is changed in what the run computes.

    python -m studies.mixture_compaction.pre --workdir W --n 144 --kappa 1 --mu 0 --element T3
    python benchmarks/newton_trace.py --scene W/runs/k1_mu0_s1/scene --out T/out [--resume] > T/trace.txt

(to start at a late stage, copy a run's output folder taken at that stage's start and
``--resume`` it).
"""

from __future__ import annotations

import argparse
import collections
from pathlib import Path


def trace(scene: Path, out: Path, resume: bool, longer: int, echo=print) -> dict:
    """Run ``scene`` into ``out`` with the trace on (module docstring); returns the counts."""
    from compute.bodies import soft, soft_matrix
    from compute.errors import StepFailure
    from compute.fem.ldl import SymbolicLDL
    from compute.run import Run
    from compute.stepping import control

    sequence: list = []
    pivots = collections.Counter()
    counts = {"attempts": 0, "failed": 0}
    settle, factorize, with_cuts = soft.SoftBodies.settle, SymbolicLDL.factorize, control.step_with_cuts
    update = soft_matrix.NewtonMatrices.update

    def traced_settle(self, step, v_old, v_new, tol):
        c = self.corrections(step, v_old, v_new)
        above = c > tol
        sequence.append((float(c.max()), int(above.sum()), int((above & (self.matrices.level > 0)).sum())))
        return settle(self, step, v_old, v_new, tol)

    def traced_update(self, data, *args):
        self.symbolic._traced_exact = data  # what update factorises at level 0 (the others: copies)
        try:
            return update(self, data, *args)
        finally:
            self.symbolic._traced_exact = None

    def traced_factorize(self, values, trying, lx, d):
        negative = factorize(self, values, trying, lx, d)
        if values is getattr(self, "_traced_exact", None):
            pivots.update(negative[trying].tolist())
        return negative

    def traced_with_cuts(attempt, state, h, max_cuts):
        def one(st, hh, deepest):
            sequence.clear()
            counts["attempts"] += 1
            try:
                result = attempt(st, hh, deepest)
            except StepFailure as exc:
                counts["failed"] += 1
                echo(f"FAIL step {state.step + 1} h {hh:.4g} its {len(sequence)}: {_line(sequence)}\n    {exc}")
                raise
            if len(sequence) > longer:
                echo(f"ok   step {state.step + 1} h {hh:.4g} its {len(sequence)}: {_line(sequence)}")
            return result
        return with_cuts(one, state, h, max_cuts)

    soft.SoftBodies.settle = traced_settle
    soft_matrix.NewtonMatrices.update = traced_update
    SymbolicLDL.factorize = traced_factorize
    control.step_with_cuts = traced_with_cuts
    try:
        Run(scene, out, resume=resume).execute()
    finally:
        soft.SoftBodies.settle, SymbolicLDL.factorize, control.step_with_cuts = settle, factorize, with_cuts
        soft_matrix.NewtonMatrices.update = update
    counts["level-0 negative pivots"] = dict(sorted(pivots.items()))
    echo(f"attempts {counts['attempts']}, failed {counts['failed']}; level-0 factorisations by negative "
         f"pivots: {counts['level-0 negative pivots']}")
    return counts


def _line(sequence) -> str:
    """'2.5e-02/144/125 1.6e-02/144/125 ...': correction / bodies above tol / of them stabilised."""
    return " ".join(f"{c:.1e}/{n}/{s}" for c, n, s in sequence)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", type=Path, required=True)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--resume", action="store_true", help="go on from the checkpoint in --out")
    ap.add_argument("--longer", type=int, default=8, help="print converged attempts above this many iterations")
    args = ap.parse_args(argv)
    trace(args.scene, args.out, args.resume, args.longer)


if __name__ == "__main__":
    main()
