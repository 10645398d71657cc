"""Where one NLGS sweep spends its time, on the contact problem of a run's next step.

Resumes RUN (a folder with scene/ and out/ holding a checkpoint; out is copied, frames left out)
with the code of the current directory's checkout, takes the first contact problem of its next
step, and times on it, one thread, ``--repeat`` passes each (per pass, in ms):

- ``sweep``: NLGS sweeps from the warm start (the solver's own kernel, ``--sweeps`` of them, no
  stopping test), per sweep;
- ``velocities``: the local velocities H_cᵀ v of every contact (what each contact reads);
- ``local solves``: the exact 2D Signorini–Coulomb solution of every contact;
- ``updates``: v += M̂⁻¹ H_c Δr_c for every contact with a nonzero impulse (what an active
  contact writes: a column of its bodies' dense compliance blocks per dof it touches).

and reports the problem's size: contacts, active ones, dense blocks and their mean size, the
bytes of the compliance values. One JSON line (--json appends it to a file).

    python benchmarks/experiments/sweep_cost.py --run W/runs/k1_mu0.2_s1
"""

from __future__ import annotations

import os

for _var in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import copy  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numba  # noqa: E402
import numpy as np  # noqa: E402

sys.path.append(str(Path(__file__).resolve().parents[1]))  # benchmarks/: the shared helpers
import checkout  # noqa: E402


class FirstProblem:
    """A contact solver that keeps a copy of the first problem it is given."""

    def __init__(self, solver):
        self.solver, self.tolerance, self.problem = solver, solver.tolerance, None

    def solve(self, problem):
        if self.problem is None:
            self.problem = copy.deepcopy(problem)
        return self.solver.solve(problem)


def first_problem(run_dir: Path):
    """The first contact problem of the next step of the run in ``run_dir``."""
    from compute.stepping import load_control

    with checkout.resumed(run_dir) as run:
        run.stepper.solver = probe = FirstProblem(run.stepper.solver)
        st, pressures = run.state, run.scene.loading.pressures
        checkout.controlled_step(load_control, run.stepper, st, pressures[st.stage - 1] if st.stage else 0.0,
                                 pressures[st.stage], lambda msg: None)
    return probe.problem


def kernels():
    """The timed loops, compiled here (they call the solver's own inlined kernels)."""
    from compute.contact.compliance import add_contact_impulse
    from compute.contact.rows import local_velocity
    from compute.solvers.nlgs import local_signorini_coulomb

    @numba.njit
    def velocities(dof, hn, ht, v):
        s = 0.0
        for c in range(dof.shape[0]):
            un, ut = local_velocity(dof, hn, ht, c, v)
            s += un + ut
        return s

    @numba.njit
    def local_solves(W, mu, b):
        s = 0.0
        for c in range(W.shape[0]):
            rn, rt = local_signorini_coulomb(W[c, 0, 0], W[c, 0, 1], W[c, 1, 0], W[c, 1, 1], b[c, 0], b[c, 1], mu[c])
            s += rn + rt
        return s

    @numba.njit
    def updates(dof, hn, ht, v, active, diagonal, block, start, offset, values):
        for c in active:
            add_contact_impulse(v, c, 1e-30, 1e-30, dof, hn, ht, diagonal, block, start, offset, values)

    return velocities, local_solves, updates


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--run", type=Path, required=True, help="a run folder with scene/ and out/ (with a checkpoint)")
    ap.add_argument("--repeat", type=int, default=10)
    ap.add_argument("--sweeps", type=int, default=10)
    ap.add_argument("--label", default="")
    ap.add_argument("--json", type=Path)
    a = ap.parse_args()
    sys.path.insert(0, os.getcwd())  # the checkout being measured
    from compute.solvers.nlgs import apply_impulses, nlgs_solve

    p = first_problem(a.run.resolve())
    carr = p.compliance.arrays()
    v = p.free_velocity()
    apply_impulses(p.dof, p.hn, p.ht, p.impulse, v, *carr)
    active = np.flatnonzero(np.any(p.impulse != 0.0, axis=1))
    b = np.random.default_rng(0).normal(size=(len(p.dof), 2))
    velocities, local_solves, updates = kernels()
    timed = {
        "sweep": (lambda: nlgs_solve(p.dof, p.hn, p.ht, p.W, p.gap_term, p.mu, p.impulse.copy(), v.copy(), v.copy(),
                                     *carr, 0, 0.0, 0.0, a.sweeps, 1.0, 0), a.sweeps),
        "velocities": (lambda: velocities(p.dof, p.hn, p.ht, v), 1),
        "local solves": (lambda: local_solves(p.W, p.mu, b), 1),
        "updates": (lambda: updates(p.dof, p.hn, p.ht, v.copy(), active, *carr), 1),
    }
    result = {"label": a.label, "commit": checkout.commit(), "contacts": len(p.dof), "active": len(active),
              "dense_blocks": len(p.compliance.start) - 1,
              "mean_block_dofs": round(float(np.diff(p.compliance.start).mean()), 1),
              "compliance_MB": round(p.compliance.values.nbytes / 1e6, 1), "ms": {}}
    for name, (f, per) in timed.items():
        f()  # compile, warm the caches
        t = time.perf_counter()
        for _ in range(a.repeat):
            f()
        result["ms"][name] = round(1e3 * (time.perf_counter() - t) / (a.repeat * per), 3)
    checkout.emit(result, a.json)


if __name__ == "__main__":
    main()
