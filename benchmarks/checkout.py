"""The checkout a benchmark measures (benchmarks run from a git worktree of another commit too),
and the helpers the benchmarks share: a run resumed from a copy of its checkpoint, the result line."""

from __future__ import annotations

import contextlib
import json
import shutil
import subprocess
import tempfile
from pathlib import Path


def commit(cwd=None) -> str:
    """Short hash of HEAD of the git checkout at ``cwd`` (the current directory by default)."""
    return subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=cwd, capture_output=True,
                          text=True, check=True).stdout.strip()


@contextlib.contextmanager
def resumed(run_dir: Path):
    """A ``compute.run.Run`` of RUN_DIR/scene resumed from a temporary copy of RUN_DIR/out (frames
    left out, the run folder untouched), quiet, with its progress kept in the copy; its history is
    closed on exit. Import after the measured checkout is on sys.path."""
    from compute.progress import RunProgress
    from compute.run import Run

    run_dir = Path(run_dir).resolve()
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "out"
        shutil.copytree(run_dir / "out", out, ignore=shutil.ignore_patterns("frames", ".lock"))
        (out / "frames").mkdir()
        run = Run(run_dir / "scene", out, resume=True, log=lambda msg: None)
        run.progress = RunProgress(out, len(run.scene.loading.pressures), None)
        _stage_settings(run)
        try:
            yield run
        finally:
            run.history.close()


def _stage_settings(run) -> None:
    """The resumed pressure stage's settings (``Run.start_stage``, in checkouts that have it):
    without them the steps measured from a checkpoint are not the run's own (the walls of a
    stage with ``walls.damping_ratio`` would ring more)."""
    pressures = run.scene.loading.pressures
    if hasattr(run, "start_stage") and run.scene.walls.control != "velocity" and run.state.stage < len(pressures):
        run.start_stage(pressures[run.state.stage])


def step(stepper, state, *load):
    """(the state after one step, its report) of a checkout's ``Stepper.step(state, *load)``:
    steps return a new State since the step-records change; older checkouts advanced ``state``
    in place and returned the report alone."""
    out = stepper.step(state, *load)
    return out if isinstance(out, tuple) else (state, out)


def controlled_step(load_control, stepper, state, *args):
    """(state, report, pressure, halvings) of a checkout's ``load_control.controlled_step``
    (older checkouts changed ``state`` in place and returned the last three)."""
    out = load_control.controlled_step(stepper, state, *args)
    return out if len(out) == 4 else (state, *out)


def emit(result: dict, json_path: Path | None) -> None:
    """Print ``result`` as one JSON line, and append it to ``json_path`` when given."""
    line = json.dumps(result)
    print(line)
    if json_path:
        with open(json_path, "a") as f:
            f.write(line + "\n")
