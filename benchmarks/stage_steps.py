"""Where a loading program's steps go, stage by stage, read from the runs' histories.

For each run folder (``RUN/out/history.csv`` or ``history.csv.gz``), per pressure stage: the
steps the stage took, the step from which φ stayed within ``--band`` of the stage's end value
(what the packing needed; the rest is the stage-end test waiting for the walls and the
inertial number), the Newton iterations, those of the steps after φ entered that band (the
work a stage-end test that stopped at the band would save) and the cut steps. The figures are counts, not
timings: they do not depend on what else the machine was doing.

With --seconds, a second table: the wall seconds of each stage, read from the progress lines of
``RUN/out/compute.log`` (elapsed time, written every 30 s, so each stage's figure is within
about 30 s; resumed runs add their sessions). Those are timings: they say what the machine was
doing too.

    python benchmarks/stage_steps.py studies/mixture_compaction/results/n1500_t3/runs/* \\
        --output stage_steps_n1500

writes benchmarks/results/OUTPUT.md (or prints the table without --output).
"""

from __future__ import annotations

import argparse
import gzip
import re
from pathlib import Path

import numpy as np

RESULTS = Path(__file__).resolve().parent / "results"


def read_history(run: Path) -> np.ndarray:
    """The structured array (steps,) of ``run``/out/history.csv, plain or gzip-compressed."""
    out = run / "out" if (run / "out").is_dir() else run
    for name, opener in (("history.csv", open), ("history.csv.gz", gzip.open)):
        if (out / name).is_file():
            with opener(out / name, "rt") as f:
                return np.genfromtxt(f, delimiter=",", names=True)
    raise FileNotFoundError(f"{out}: no history.csv or history.csv.gz")


def stage_counts(history: np.ndarray, band: float) -> list[dict]:
    """Per stage: steps, steps until φ stays within ``band`` (absolute) of the stage's last φ,
    Newton iterations, Newton iterations of the steps after that, steps with cuts, and the
    stage's last φ."""
    rows = []
    stages = history["stage"].astype(int)
    for s in np.unique(stages):
        h = history[stages == s]
        phi = h["phi"]
        outside = np.flatnonzero(np.abs(phi - phi[-1]) > band)
        plateau = int(outside[-1] + 1) if len(outside) else 0
        newton = h["newton_iterations"]
        rows.append({"stage": int(s), "P": float(h["pressure_applied"][-1]), "steps": len(h),
                     "plateau": plateau, "newton": int(newton.sum()), "newton_after": int(newton[plateau:].sum()),
                     "cut_steps": int(np.count_nonzero(h["cuts"])), "phi": float(phi[-1])})
    return rows


PROGRESS = re.compile(r"compute: stage (\d+)/\d+ .* (\d+(?::\d+)+) ETA")


def stage_seconds(log: Path) -> dict[int, float]:
    """Wall seconds per stage (index from 0) from a compute.log: each progress line's elapsed
    time since the previous line (or the session's start, a line starting with "===") goes to
    the stage that line names."""
    seconds: dict[int, float] = {}
    previous = 0.0
    for line in log.read_text().splitlines():
        if line.startswith("==="):
            previous = 0.0
            continue
        m = PROGRESS.match(line)
        if m:
            elapsed = float(sum(int(x) * 60**i for i, x in enumerate(reversed(m.group(2).split(":")))))
            stage = int(m.group(1)) - 1
            seconds[stage] = seconds.get(stage, 0.0) + elapsed - previous
            previous = elapsed
    return seconds


def seconds_table(runs: list[Path]) -> str:
    lines = ["Wall seconds per stage (compute.log progress lines, within about 30 s each).", "",
             "| run | " + " | ".join(f"stage {i}" for i in range(7)) + " | run |", "|---|" + "---|" * 8]
    for run in runs:
        t = stage_seconds((run / "out" if (run / "out").is_dir() else run) / "compute.log")
        cells = [f"{t.get(i, 0.0):.0f}" for i in range(max(t, default=-1) + 1)]
        lines.append(f"| {run.parent.parent.name}/{run.name} | " + " | ".join(cells + [""] * (7 - len(cells)))
                     + f" | {sum(t.values()):.0f} |")
    return "\n".join(lines) + "\n"


def table(runs: list[Path], band: float) -> str:
    lines = [f"Per stage: steps / steps until φ stays within {band:g} of the stage's end φ / Newton "
             "iterations (of which after those steps). Last column: all steps, all Newton iterations "
             "and the share of them after each stage's band was entered.", "",
             "| run | " + " | ".join(f"stage {i}" for i in range(7)) + " | run |",
             "|---|" + "---|" * 8]
    for run in runs:
        rows = stage_counts(read_history(run), band)
        cells = [f"{r['steps']} / {r['plateau']} / {r['newton']} ({r['newton_after']})" for r in rows]
        newton = sum(r["newton"] for r in rows)
        after = sum(r["newton_after"] for r in rows)
        total = f"{sum(r['steps'] for r in rows)} / {newton} ({after / max(newton, 1):.0%} after)"
        lines.append(f"| {run.parent.parent.name}/{run.name} | " + " | ".join(cells + [""] * (7 - len(cells)))
                     + f" | {total} |")
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", type=Path, nargs="+", help="run folders (holding out/history.csv[.gz])")
    ap.add_argument("--band", type=float, default=5e-4, help="φ band around a stage's end value (default 5e-4)")
    ap.add_argument("--seconds", action="store_true", help="also the wall seconds per stage, from compute.log")
    ap.add_argument("--output", help="write benchmarks/results/OUTPUT.md instead of printing")
    a = ap.parse_args()
    text = table(sorted(a.runs), a.band) + ("\n" + seconds_table(sorted(a.runs)) if a.seconds else "")
    if a.output:
        (RESULTS / f"{a.output}.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
