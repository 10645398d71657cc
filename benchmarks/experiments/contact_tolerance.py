"""Run time against error for a mixture: the contact solver, its tolerance and the time step.

The 144-disk κ = 0.5, μ = 0.2, T3 × 92 mixture (prepared as in soft_step_cost.py) compacted
through P/E = 0.01, 0.03, 0.1, 0.3, once per case, one process each (``python -m compute``, one
thread): solver.contact_tolerance (the natural-map error each solve must reach) for nlgs and, at the looser
tolerances, the block solver, at the study's h = 0.5; and nlgs at 1e-4 with h = 0.25 and 1. Each case reports its
wall time, steps, Newton iterations, cuts, contact misses (steps whose solve stopped above the
tolerance, summary.json) and the error of φ at every equilibrated stage against the reference
case (nlgs at ``--reference`` tolerance, h = 0.5).

    python benchmarks/experiments/contact_tolerance.py --workdir W [--tolerances 1e-2 1e-3 1e-4 1e-5 1e-6]

Cases already run in W (W/cases/<case>/result.json) are not run again.

Writes benchmarks/results/contact_tolerance.{md,json}.
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import time
from pathlib import Path

sys.path.append(str(Path(__file__).resolve().parents[1]))  # benchmarks/: the shared helpers
from soft_step_cost import RESULTS, _child_env, prepare  # noqa: E402

PRESSURES = (0.01, 0.03, 0.1, 0.3)


def case_scene(base: Path, folder: Path, contact: str, tol: float, h: float, sweeps: int) -> Path:
    """A copy of the scene ``base`` with the solver settings of one case."""
    from pre.scene import copy_scene

    if folder.exists():
        shutil.rmtree(folder)
    return copy_scene(base, folder, {"solver.contact": contact, "solver.contact_tolerance": tol,
                                     "solver.nlgs_max_sweeps": sweeps, "solver.time_step": h})


def run_case(scene: Path, out: Path) -> dict:
    from post.table import measure_output

    if out.exists():
        shutil.rmtree(out)
    t0 = time.perf_counter()
    code = subprocess.run([sys.executable, "-m", "compute", str(scene), "--out", str(out), "--threads", "1"],
                          env=_child_env(1), capture_output=True, text=True).returncode
    wall = time.perf_counter() - t0
    summary = json.loads((out / "summary.json").read_text()) if (out / "summary.json").is_file() else None
    rows = [r for r in measure_output(out, min_contacts=1) if r["equilibrated"]] if (out / "frames.csv").is_file() else []
    return {"exit": code, "wall": wall, "phi": [r["phi"] for r in rows],
            "status": summary["status"] if summary else "failed",
            "steps": summary["steps"] if summary else None,
            "newton": sum(s["newton_iterations"] for s in summary["stages"]) if summary else None,
            "cuts": sum(s["cuts"] for s in summary["stages"]) if summary else None,
            "misses": summary["contact_misses"] if summary else None}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--workdir", type=Path, required=True)
    ap.add_argument("--tolerances", type=float, nargs="+", default=[1e-2, 1e-3, 1e-4, 1e-5, 1e-6])
    ap.add_argument("--block-tolerances", type=float, nargs="+", default=[1e-2, 1e-3, 1e-4],
                    help="tolerances of the block solver (slower per sweep than nlgs on a mixture)")
    ap.add_argument("--reference", type=float, default=1e-7)
    ap.add_argument("--max-sweeps", type=int, default=20000)
    a = ap.parse_args(argv)
    base = prepare(a.workdir, 144, 0.5, 0.2, "T3", PRESSURES)
    cases = [("nlgs", a.reference, 0.5)] + [("nlgs", t, 0.5) for t in a.tolerances]
    cases += [("block", t, 0.5) for t in a.block_tolerances] + [("nlgs", 1e-4, h) for h in (0.25, 1.0)]
    results = []
    for contact, tol, h in cases:
        name = f"{contact}_tol{tol:g}_h{h:g}"
        done = a.workdir / "cases" / name / "result.json"
        if done.is_file():  # a case finished by an earlier call
            r = json.loads(done.read_text())
        else:
            scene = case_scene(base, a.workdir / "cases" / name / "scene", contact, tol, h, a.max_sweeps)
            r = run_case(scene, a.workdir / "cases" / name / "out")
            done.write_text(json.dumps(r) + "\n")
        results.append({"contact": contact, "tolerance": tol, "h": h, **r})
        print(f"{name}: {r['wall']:.1f} s, {r['status']}, phi {r['phi']}", flush=True)
    ref = results[0]["phi"]
    lines = ["# Run time against error: contact solver, tolerance, time step (144-disk mixture)", "",
             f"`python benchmarks/experiments/contact_tolerance.py --workdir W`; κ = 0.5, μ = 0.2, T3 × 92, P/E = "
             f"{', '.join(map(str, PRESSURES))}; one thread; reference: nlgs at {a.reference:g}, h = 0.5 "
             f"(φ = {', '.join(f'{p:.6f}' for p in ref)}). |Δφ|: largest over the equilibrated stages.", "",
             "| contact | tolerance | h | wall s | status | steps | Newton iterations | cuts | contact misses | "
             "max abs Δφ |", "|---|---|---|---|---|---|---|---|---|---|"]
    for r in results:
        n = min(len(r["phi"]), len(ref))
        dphi = max((abs(x - y) for x, y in zip(r["phi"][:n], ref[:n])), default=float("nan"))
        stages = "" if len(r["phi"]) == len(ref) else f" ({len(r['phi'])} of {len(ref)} stages)"
        lines.append(f"| {r['contact']} | {r['tolerance']:g} | {r['h']:g} | {r['wall']:.1f} | {r['status']}{stages} | "
                     f"{r['steps']} | {r['newton']} | {r['cuts']} | {r['misses']} | {dphi:.2e} |")
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "contact_tolerance.md").write_text("\n".join(lines) + "\n")
    (RESULTS / "contact_tolerance.json").write_text(json.dumps(results, indent=1) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
