"""The end of a run: ``summary.json`` and the status marker, from the output folder itself.

A run that went through its whole loading program ends

- ``COMPLETE`` when every pressure stage was equilibrated and every step's contact solve reached
  its tolerance;
- ``INCOMPLETE`` otherwise: the file gives the diagnosis of a stage that stalled
  (compute.stall: the run ended there), lists the stages ended by ``max_steps_per_stage`` (or
  never run after a stall) and the
  number of steps whose contact solve stopped above its tolerance (the frames and history are
  all there, but some numbers are not what the scene asked for).

Both are derived from ``history.csv`` and ``frames.csv``, so a resumed run counts its steps from
before the resume too. ``summary.json``: per stage its target pressure, steps, whether it was
equilibrated, Newton iterations, cuts, load-increment halvings, sub-steps (of the steps whose
history records them), contact misses and the largest contact residual; and the totals:
``steps`` the run's last step, ``history_missing_steps`` the ranges of steps without a row in
``history.csv`` (compute.output.History; the per-stage sums leave them out), ``stalled`` the
diagnosis of a stalled stage (null when none stalled). :func:`run_status` reads a run's state
back from these files (and FAILED, the checkpoint) for whoever resumes or collects runs.
"""

from __future__ import annotations

import json
from pathlib import Path

from compute import files, output

MARKERS = ("COMPLETE", "INCOMPLETE")


def run_status(out: str | Path) -> str:
    """The state of the run in ``out``, from its files: ``complete`` or ``incomplete`` (the
    marker), ``failed`` (OUT/FAILED), ``partial`` (a checkpoint, no marker) or ``new``."""
    out = Path(out)
    if (out / "COMPLETE").is_file():
        return "complete"
    if (out / "INCOMPLETE").is_file():
        return "incomplete"
    if (out / "FAILED").is_file():
        return "failed"
    if (out / output.CHECKPOINT).is_file():
        return "partial"
    return "new"


def run_summary(out: Path, scene, last_step: int, stalled: str | None = None) -> dict:
    """The summary (module docstring) of the run in ``out`` of ``scene``, which ended at step
    ``last_step``; ``stalled``: the diagnosis of the stage that ended it early (compute.stall)."""
    tol = scene.solver.contact_tolerance
    history = output.read_csv_rows(out / "history.csv")
    frames = output.read_frame_rows(out / "frames.csv")
    pressure_control = scene.walls.control == "pressure"
    stages = []
    n_stages = len(scene.loading.pressures) if pressure_control else 1
    for s in range(n_stages):
        rows = [r for r in history if int(r["stage"]) == s]
        last = [f for f in frames if int(f["stage"]) == s]
        residuals = [float(r["nlgs_residual"]) for r in rows]
        stages.append({
            "stage": s,
            "pressure": scene.loading.pressures[s] if pressure_control else None,
            "steps": len(rows),
            "equilibrated": bool(last) and last[-1]["equilibrated"] == "1",
            "newton_iterations": sum(int(r["newton_iterations"]) for r in rows),
            "cuts": sum(int(r["cuts"]) for r in rows),
            "load_halvings": sum(int(r["load_halvings"]) for r in rows),
            "sub_steps": sum(int(r["sub_steps"]) for r in rows if r.get("sub_steps")),  # empty: resumed older history
            "contact_misses": sum(x > tol for x in residuals),
            "max_contact_residual": max(residuals, default=0.0),
        })
    not_equilibrated = [s["stage"] for s in stages if pressure_control and not s["equilibrated"]]
    misses = sum(s["contact_misses"] for s in stages)
    return {
        "status": "complete" if not not_equilibrated and not misses and not stalled else "incomplete",
        "stalled": stalled,
        "steps": last_step,
        "history_missing_steps": output.missing_steps([int(r["step"]) for r in history], last_step),
        "contact_tolerance": tol,
        "stages_not_equilibrated": not_equilibrated,
        "contact_misses": misses,
        "stages": stages,
    }


def write(out: Path, summary: dict) -> None:
    """Write ``summary.json`` and COMPLETE or INCOMPLETE (removing the other) for the run in
    ``out`` whose :func:`run_summary` is ``summary``."""
    files.write_text(out / "summary.json", json.dumps(summary, indent=1) + "\n")
    for name in MARKERS:
        files.remove(out / name)
    steps = f"{summary['steps']} steps, {len(output.read_frame_rows(out / 'frames.csv'))} frames\n"
    if summary["status"] == "complete":
        files.write_text(out / "COMPLETE", steps)
    else:
        files.write_text(out / "INCOMPLETE", steps + incomplete_reasons(summary) + "\n")


def incomplete_reasons(summary: dict) -> str:
    """One line per reason why a finished run is not COMPLETE."""
    lines = []
    if summary.get("stalled"):
        lines.append(summary["stalled"])
    if summary["stages_not_equilibrated"]:
        lines.append(f"stages not equilibrated within max_steps_per_stage: {summary['stages_not_equilibrated']}")
    if summary["contact_misses"]:
        worst = max(s["max_contact_residual"] for s in summary["stages"])
        lines.append(f"{summary['contact_misses']} of {summary['steps']} steps ended with a contact residual above "
                     f"solver.contact_tolerance = {summary['contact_tolerance']:g} (largest {worst:.3g})")
    return "\n".join(lines)
