"""Newton iterations per step of soft scenes, for comparing two versions of compute.

Measures the checkout of the current directory (so that a git worktree of another commit can run
this same script), one thread, one JSON line per case (--json appends them to a file):

- ``single``: the single-particle study's default scene (16 stages to P/E = 1) at the time
  steps --single-h; the iteration counts of this scene jump by tens of percent with h (the
  body's rigid rotation is unstable under the load), so several h are run; ``single_free``: the
  same with the rotation free (--single-free, checkouts that hold it by default);
- ``three``: three soft T3 disks pressed by the walls with friction 0.3, contact tolerance 1e-3,
  Newton tolerance 1e-9 (tests/deformable/test_newton_residual.py's scene), 8 steps at each
  time step --three-h;
- ``program``: a prepared scene folder (--program, e.g. the 144-disk mixture), its whole loading
  program, the run ending where it ends (a failure is part of the result).

Runs of scene folders also record the Newton iterations and seconds of each stage
(``stage_iterations``, ``stage_seconds``; the first stage's seconds include loading numba's
cache).

    python benchmarks/newton_iterations.py --json after.jsonl [--program W/runs/k0.5_mu0.2_s1/scene]
    (cd WORKTREE && python /path/to/benchmarks/newton_iterations.py --json before.jsonl ...)
"""

from __future__ import annotations

import os

for _var in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import csv  # noqa: E402
import inspect  # noqa: E402
import io  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import checkout  # noqa: E402


def run_folder(scene: Path, out: Path) -> dict:
    """Run a scene's loading program; counts, wall time, end status, final φ and the last φ of
    every stage (``stage_phi``)."""
    from compute.errors import SimulationError
    from compute.run import Run

    try:
        from compute.progress import Display
    except ImportError:  # checkouts before the progress display
        Display = None

    t0 = time.perf_counter()
    quiet = {"display": Display(1, stream=io.StringIO())} if "display" in inspect.signature(Run).parameters else {}
    run = Run(scene, out, log=lambda m: None, **quiet)  # checkouts before the progress display: none
    per_stage = count_per_stage(run)
    try:
        state = run.execute()
        end = "ok"
    except SimulationError as exc:
        state, end = run.state, f"failed at step {run.state.step + 1}: {str(exc)[:120]}"
    s = run.stepper.stats
    return {"steps": state.step, "newton_iterations": s["newton_iterations"], "contact_sweeps": s["nlgs_sweeps"],
            "cuts": s.get("cuts", 0), "fallbacks": s.get("fallbacks", 0), "seconds": round(time.perf_counter() - t0, 2), "phi": round(run.model.phi(state.q), 6),
            "end": end, "stage_phi": stage_phi(out), **per_stage}


def count_per_stage(run) -> dict:
    """Wrap ``run.stepper.step`` so that the Newton iterations and the seconds of every step
    (failed attempts included) add up per stage, in the returned dict's lists
    ``stage_iterations`` and ``stage_seconds`` (filled as the run goes; works on checkouts
    whose history has no iteration column)."""
    stepper, counts = run.stepper, {"stage_iterations": [], "stage_seconds": []}
    step = stepper.step

    def counted(state, *args, **kwargs):
        its, t = stepper.stats["newton_iterations"], time.perf_counter()
        try:
            return step(state, *args, **kwargs)
        finally:
            for key in counts:
                counts[key].extend([0] * (state.stage + 1 - len(counts[key])))
            counts["stage_iterations"][state.stage] += stepper.stats["newton_iterations"] - its
            counts["stage_seconds"][state.stage] = round(counts["stage_seconds"][state.stage]
                                                         + time.perf_counter() - t, 4)

    stepper.step = counted
    return counts


def stage_phi(out: Path) -> list[float]:
    """φ at the last step of every stage of OUT/history.csv (the equilibrated φ of the ended ones)."""
    last = {}
    with open(out / "history.csv") as f:
        for row in csv.DictReader(f):
            last[int(row["stage"])] = round(float(row["phi"]), 7)
    return [last[s] for s in sorted(last)]


def three_disks(folder: Path, h: float, steps: int = 8) -> dict:
    """The pressed three-disk scene at time step h: counts over ``steps`` steps."""
    from tests.deformable import scenes

    model, stepper, state = scenes.pressed_three(folder, 0.3, h)
    t0, end = time.perf_counter(), "ok"
    try:
        for _ in range(steps):
            state, _ = checkout.step(stepper, state, 0.05)
    except Exception as exc:  # a failed step ends the case; it is part of the result
        end = f"{type(exc).__name__}: {str(exc)[:120]}"
    s = stepper.stats
    return {"steps": state.step, "newton_iterations": s["newton_iterations"], "cuts": s["cuts"],
            "seconds": round(time.perf_counter() - t0, 2), "end": end}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--single-h", type=float, nargs="*", default=[8.0, 9.0, 10.0, 11.0, 12.0])
    ap.add_argument("--single-free", type=float, nargs="*", default=[], help="time steps of single_free")
    ap.add_argument("--three-h", type=float, nargs="*", default=[0.5, 1.0, 2.0])
    ap.add_argument("--program", type=Path, nargs="*", default=[], help="scene folders run through their program")
    ap.add_argument("--label", default="")
    ap.add_argument("--json", type=Path)
    a = ap.parse_args()
    sys.path.insert(0, os.getcwd())  # the checkout being measured
    from pre.single_particle import write

    commit = checkout.commit()
    lines = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        cases = [("single", h, lambda h=h: run_folder(write(tmp / f"single{h}", time_step=h), tmp / f"single{h}_out"))
                 for h in a.single_h]
        cases += [("single_free", h, lambda h=h: run_folder(write(tmp / f"free{h}", time_step=h, hold_rotation=False),
                                                           tmp / f"free{h}_out")) for h in a.single_free]
        cases += [("three", h, lambda h=h: three_disks(tmp / f"three{h}", h)) for h in a.three_h]
        cases += [("program", str(p), lambda p=p: run_folder(p.resolve(), tmp / f"program{k}"))
                  for k, p in enumerate(a.program)]
        for name, parameter, case in cases:
            result = {"label": a.label, "commit": commit, "case": name, "parameter": parameter, **case()}
            lines.append(json.dumps(result))
            print(lines[-1], flush=True)
    if a.json:
        with open(a.json, "a") as f:
            f.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
