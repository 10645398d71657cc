"""Contact problems of real runs, saved to files and solved by every contact solver side by side.

``export``: runs a scene (compute's Run, one thread) and saves the contact problem of the first
contact solve of the first step of stage ``--stage`` (or of step ``--step``) as a .npz file,
cold (impulses zero), then stops the run. With ``--run`` it resumes a run from its checkpoint
instead (a copy, ``benchmarks/checkout.py``); ``--count K`` saves the next K solves (FILE_000.npz,
…) and ``--warm`` keeps their warm-start impulses. ``compare``: solves saved problems (from their
warm start if saved so, else from zero impulses) with each solver to each tolerance and prints
one JSON line per solve: iterations, seconds,
the natural-map error (compute.contact.residual, the stopping test) and the velocity error
(natural-map error in velocity units relative to the free velocity's scale), both
recomputed from the returned impulses.

    python -m studies.mixture_compaction.pre --workdir W3 --n 144 --kappa 0.5 --mu 0.2 --element T3 --pressures 0.01 0.03 0.1 0.3 1
    python benchmarks/contact_problems.py export --scene W3/runs/k0.5_mu0.2_s1/scene --stage 4 --file P/mix144_pe1.npz
    python benchmarks/contact_problems.py export --scene studies/mixture_compaction/results/n1500_t3/rigid/mu0.2_s1/scene --step 1 --file P/rigid1500.npz
    python benchmarks/contact_problems.py compare P/*.npz --solvers nlgs block interior_point --tolerances 1e-6 1e-8
    python benchmarks/contact_problems.py compare P/rigid1500.npz --solvers interior_point --friction 0.05
    python benchmarks/contact_problems.py compare P/mix1500.npz --solvers mprgp --tolerances 1e-4 --screening 0 0.1
    python benchmarks/contact_problems.py export --run W/runs/k0.8_mu0_s2 --stage 5 --count 40 --warm --file P/k08.npz
    python benchmarks/contact_problems.py compare P/k08_*.npz --solvers mprgp --tolerances 1e-4 --screening 0.1
"""

from __future__ import annotations

import os

for _var in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import contextlib  # noqa: E402
import copy  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.append(str(Path(__file__).resolve().parent))  # benchmarks/: the shared helpers
import checkout  # noqa: E402

FIELDS = ("dof", "hn", "ht", "v_free", "gap_term", "mu")
COMPLIANCE = ("order", "index", "diagonal", "block", "start", "offset", "values")


class _Saved(BaseException):
    """Ends the exporting run once the problem is written."""


def save(problem, path: Path, warm: bool = False, **meta) -> None:
    """The problem's rows, compliance and free velocity (not W: recomputed on load) to ``path``,
    with its impulses if ``warm``."""
    arrays = {k: getattr(problem, k) for k in FIELDS + (("impulse",) if warm else ())}
    arrays.update({"c_" + k: getattr(problem.compliance, k) for k in COMPLIANCE})
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, meta=json.dumps(meta), **arrays)


def load(path: Path):
    """The ContactProblem saved in ``path``, with its saved warm start or zero impulses; and its metadata."""
    from compute.contact.compliance import Compliance, delassus_blocks
    from compute.contact.problem import ContactProblem

    z = np.load(path)
    comp = Compliance(*(z["c_" + k] for k in COMPLIANCE))
    W = np.empty((len(z["gap_term"]), 2, 2))
    delassus_blocks(z["dof"], z["hn"], z["ht"], *comp.arrays(), W)
    impulse = z["impulse"].copy() if "impulse" in z else np.zeros((len(z["gap_term"]), 2))
    p = ContactProblem(z["dof"], z["hn"], z["ht"], W, comp, z["v_free"].copy(), z["gap_term"], z["mu"], impulse)
    return p, json.loads(str(z["meta"]))


def export(a) -> None:
    from compute.run import Run

    with contextlib.ExitStack() as stack:
        if a.run:
            run = stack.enter_context(checkout.resumed(a.run))
        else:
            tmp = stack.enter_context(tempfile.TemporaryDirectory())
            run = Run(a.scene, Path(tmp) / "out", display=None, log=lambda msg: None)
        inner = run.stepper.solver
        saved = []

        class Recorder:
            tolerance = inner.tolerance
            measure = inner.measure

            def solve(self, problem):
                st = run.state
                if (a.step is not None and st.step + 1 >= a.step) or (a.stage is not None and st.stage >= a.stage):
                    path = a.file if a.count == 1 else a.file.with_name(f"{a.file.stem}_{len(saved):03d}.npz")
                    save(problem, path, a.warm, scene=str(a.scene or a.run), step=st.step + 1, stage=st.stage,
                         contacts=len(problem), dofs=len(problem.compliance))
                    saved.append(path)
                    if len(saved) == a.count:
                        raise _Saved
                return inner.solve(problem)

        run.stepper.solver = Recorder()
        try:
            run.execute()
        except _Saved:
            print(f"saved {len(saved)} problems: {saved[0]} …", file=sys.stderr)
            return
        raise SystemExit("the run ended before the requested step or stage")


def solver_of(name: str, tol: float, soft: bool, sweeps: int = 200_000):
    """Solver ``name`` to ``tol``, the Gauss–Seidel ones with ``sweeps`` sweeps (block: a quarter);
    ``soft``: the problem has soft bodies (nlgs_ip's fallback depends on it, as in a scene)."""
    from compute.solvers.block_gs import BlockGS
    from compute.solvers.cone_point import ConePoint
    from compute.solvers.interior_point import InteriorPoint
    from compute.solvers.mprgp import MPRGP
    from compute.solvers.nlgs import NLGS
    from compute.solvers.nlgs_then import NLGSThen

    return {"mprgp": lambda: MPRGP(tol, sweeps), "nlgs": lambda: NLGS(tol, sweeps), "block": lambda: BlockGS(tol, sweeps // 4),
            "nlgs_block": lambda: NLGSThen.block(tol, sweeps), "interior_point": lambda: InteriorPoint(tol),
            "nlgs_ip": lambda: NLGSThen.interior_point(tol, sweeps, soft=soft), "cone_point": lambda: ConePoint(tol)}[name]()


def compare(a) -> None:
    for path in a.problems:
        base, meta = load(path)
        if a.friction is not None:  # the same problem with another friction coefficient
            base.mu[base.mu > 0.0] = a.friction
        for name in a.solvers:
            for tol, margin in ((t, m) for t in a.tolerances for m in a.screening):
                p = copy.deepcopy(base)
                solver = solver_of(name, tol, len(base.compliance.start) > 1, a.sweeps)
                if margin > 0.0:
                    from compute.solvers.screened import Screened

                    solver = Screened(solver, margin)
                solver.solve(copy.deepcopy(base))  # compile, warm caches
                t = time.perf_counter()
                rep = solver.solve(p)
                seconds = time.perf_counter() - t
                print(json.dumps({"problem": Path(path).stem, "contacts": meta["contacts"], "solver": name,
                                  "screening": margin,
                                  "tolerance": tol, "iterations": rep.iterations, "seconds": round(seconds, 3),
                                  "error": float(f"{p.error(rep.v):.3g}"),
                                  "velocity_error": [float(f"{e:.3g}") for e in p.velocity_error(rep.v)]}), flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="command", required=True)
    e = sub.add_parser("export")
    source = e.add_mutually_exclusive_group(required=True)
    source.add_argument("--scene", type=Path, help="run this scene from its start")
    source.add_argument("--run", type=Path, help="resume this run folder (scene/, out/) from its checkpoint")
    e.add_argument("--file", type=Path, required=True)
    e.add_argument("--count", type=int, default=1, help="save this many successive solves")
    e.add_argument("--warm", action="store_true", help="keep the warm-start impulses (default: zero)")
    g = e.add_mutually_exclusive_group(required=True)
    g.add_argument("--stage", type=int)
    g.add_argument("--step", type=int)
    c = sub.add_parser("compare")
    c.add_argument("problems", nargs="+", type=Path)
    c.add_argument("--solvers", nargs="+", default=["nlgs", "block", "interior_point"])
    c.add_argument("--tolerances", nargs="+", type=float, default=[1e-6, 1e-8])
    c.add_argument("--friction", type=float, help="set every frictional contact's μ to this value")
    c.add_argument("--sweeps", type=int, default=200_000, help="sweep budget of the Gauss–Seidel solvers "
                   "(a scene's nlgs_max_sweeps; nlgs_ip hands over where NLGS would exceed it)")
    c.add_argument("--screening", nargs="+", type=float, default=[0.0],
                   help="solver.contact_screening margins to solve with (0: every row; compute.solvers.screened)")
    a = ap.parse_args()
    if a.command == "export" and a.count < 1:
        ap.error(f"export --count: expected at least 1 problem to save, got {a.count}")
    sys.path.insert(0, os.getcwd())  # the checkout being measured
    export(a) if a.command == "export" else compare(a)


if __name__ == "__main__":
    main()
