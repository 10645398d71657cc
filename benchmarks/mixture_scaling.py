"""Run time and memory of one mixture run against the number of disks N.

For each N: the mixture study's pre stage (jamming of N rigid disks, then a fraction κ made soft,
--element × 92 per soft disk; T6 with its default standard volumetric term) into
WORKDIR/n<N>_<element>/, then its one run with ``python -m compute --resume``
as a child process: wall time and peak resident memory of that process (``os.wait4``), steps,
Newton iterations and, per stage, φ and the step at which it ended. A run interrupted (the
benchmark killed) resumes from its checkpoint when the benchmark is started again; the wall
times of the sessions add up. Results are rewritten after every run:
benchmarks/results/mixture_scaling_<element>.{md,json}.

    python benchmarks/mixture_scaling.py --workdir /tmp/scaling --n 30 144 500 1500 --element T6
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import checkout

ROOT = Path(__file__).resolve().parents[1]
RESULTS = Path(__file__).resolve().parent / "results"


def prepare(work: Path, n: int, kappa: float, mu: float, p_max: float, stages: int, element: str) -> Path:
    """The scene of the run (the study's pre stage, once)."""
    study = work / f"n{n}_{element}"
    if not (study / "study.json").is_file():
        subprocess.run([sys.executable, "-m", "studies.mixture_compaction.pre", "--workdir", str(study), "--n", str(n),
                        "--kappa", str(kappa), "--mu", str(mu), "--p-min", "1e-3", "--p-max", str(p_max),
                        "--stages", str(stages), "--element", element], cwd=ROOT, check=True, stdout=subprocess.DEVNULL)
    run = json.loads((study / "study.json").read_text())["runs"][0]
    return study / run["scene"], study / run["out"]


def run(scene: Path, out: Path, checkpoint_minutes: float | None) -> dict:
    """Run (or resume) the scene in a child process: wall seconds, peak RSS in MiB, exit code, the
    commit measured and the machine's 1-minute load average when it started."""
    env = dict(os.environ, NUMBA_NUM_THREADS="1", OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    commit = checkout.commit(ROOT)
    load = os.getloadavg()[0]  # what else runs on the machine (timings on a shared machine are upper bounds)
    t0 = time.perf_counter()
    with open(out.parent / "scaling.log", "a") as log:
        extra = ["--checkpoint-minutes", str(checkpoint_minutes)] if checkpoint_minutes else []
        proc = subprocess.Popen([sys.executable, "-m", "compute", str(scene), "--out", str(out), "--resume", *extra],
                                cwd=ROOT, env=env, stdout=log, stderr=subprocess.STDOUT)
        _, status, usage = os.wait4(proc.pid, 0)
    return {"seconds": time.perf_counter() - t0, "peak_mib": usage.ru_maxrss / 1024.0,
            "exit": os.waitstatus_to_exitcode(status), "commit": commit, "load_at_start": load}


def describe(out: Path) -> dict:
    """Steps, Newton iterations and the stages of a finished (or partial) run, from its files."""
    history = list(csv.DictReader(open(out / "history.csv")))
    frames = [r for r in csv.DictReader(open(out / "frames.csv")) if r["equilibrated"] == "1"]
    return {"steps": len(history), "newton_iterations": sum(int(r["newton_iterations"]) for r in history),
            "status": next((m.lower() for m in ("COMPLETE", "INCOMPLETE", "FAILED") if (out / m).is_file()), "partial"),
            "stages": [{"P": float(r["pressure_applied"]), "step": int(r["step"])} for r in frames]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--workdir", required=True)
    ap.add_argument("--n", type=int, nargs="+", default=[30, 144, 500, 1500])
    ap.add_argument("--kappa", type=float, default=1.0)
    ap.add_argument("--mu", type=float, default=0.2)
    ap.add_argument("--p-max", type=float, default=1.0)
    ap.add_argument("--stages", type=int, default=7)
    ap.add_argument("--element", choices=("T3", "T6"), default="T6")
    ap.add_argument("--checkpoint-minutes", type=float, help="passed to compute (long runs across sessions)")
    a = ap.parse_args()
    work = Path(a.workdir)
    RESULTS.mkdir(exist_ok=True)
    record_file = RESULTS / f"mixture_scaling_{a.element}.json"
    record = json.loads(record_file.read_text()) if record_file.is_file() else {}
    for n in a.n:
        scene, out = prepare(work, n, a.kappa, a.mu, a.p_max, a.stages, a.element)
        entry = record.setdefault(str(n), {"sessions": []})
        if not (out / "COMPLETE").is_file() and not (out / "INCOMPLETE").is_file():
            entry["sessions"].append(run(scene, out, a.checkpoint_minutes))
        entry.update(describe(out), kappa=a.kappa, mu=a.mu, seconds=sum(s["seconds"] for s in entry["sessions"]),
                     peak_mib=max((s["peak_mib"] for s in entry["sessions"]), default=float("nan")))
        record_file.write_text(json.dumps(record, indent=1) + "\n")
        print(f"N = {n}: {entry['status']}, {entry['steps']} steps, {entry['seconds']:.0f} s, "
              f"{entry['peak_mib']:.0f} MiB", flush=True)
        _markdown(record, a)


def _markdown(record: dict, a) -> None:
    lines = [f"# One mixture run against N (κ = {a.kappa:g}, μ = {a.mu:g}, {a.element} × 92, P/E = 1e-3 … {a.p_max:g} in "
             f"{a.stages} stages, one thread)", "",
             f"`python benchmarks/mixture_scaling.py --workdir W --element {a.element} --n " + " ".join(record)
             + "`: the compute stage as "
             "one child process (`python -m compute --resume`), its wall time summed over sessions and its peak "
             "resident memory; pre (jamming) not counted.", "",
             "Sessions: the commit measured and the machine's 1-minute load average as it started (above 1, other "
             "work shared the cores and the wall time is an upper bound; not recorded before this column existed).",
             "",
             "| N | status | steps | Newton iterations | wall time (s) | s/step | peak memory (MiB) | stage ends (step) "
             "| sessions |",
             "|---|---|---|---|---|---|---|---|---|"]
    for n, e in sorted(record.items(), key=lambda kv: int(kv[0])):
        ends = ", ".join(str(s["step"]) for s in e["stages"])
        sessions = ", ".join(f"{s['commit']} (load {s['load_at_start']:.1f})" if "commit" in s else "not recorded"
                             for s in e["sessions"])
        lines.append(f"| {n} | {e['status']} | {e['steps']} | {e['newton_iterations']} | {e['seconds']:.0f} | "
                     f"{e['seconds'] / max(e['steps'], 1):.3f} | {e['peak_mib']:.0f} | {ends} | {sessions} |")
    (RESULTS / f"mixture_scaling_{a.element}.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
