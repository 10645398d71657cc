"""A run killed mid-way and resumed with --resume ends where an uninterrupted run ends."""

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from compute.errors import OutputFolderError
from compute.output import HISTORY_COLUMNS, History, read_frame_rows
from compute.run import run
from tests.compute.scenes import rigid_scene


def _scene(folder: Path) -> Path:
    return rigid_scene(folder, 40, 3, 25, 100)


def _frames(out: Path) -> list[int]:
    return [int(r["frame"]) for r in read_frame_rows(out / "frames.csv")]


def test_killed_and_resumed_run_matches_uninterrupted(tmp_path):
    scene = _scene(tmp_path / "scene")
    reference = run(scene, tmp_path / "ref", log=lambda m: None)

    out = tmp_path / "killed"
    cmd = [sys.executable, "-m", "compute", str(scene), "--out", str(out)]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    ckpt = out / "checkpoint" / "state.npz"
    deadline = time.time() + 120
    while time.time() < deadline and proc.poll() is None:
        if ckpt.is_file() and ckpt.stat().st_size > 0:
            with np.load(ckpt) as d:
                if d["scalars"][1] >= 200:  # past step 200: kill it mid-way
                    break
        time.sleep(0.05)
    assert proc.poll() is None, "the run finished before it could be killed: make it longer"
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    with np.load(ckpt) as d:
        killed_at = int(d["scalars"][1])
    assert killed_at < reference.step

    resumed = subprocess.run(cmd + ["--resume"], capture_output=True, text=True)
    assert resumed.returncode == 0, resumed.stderr
    with np.load(ckpt) as d:
        q = d["q"]
    box = reference.q[-4:]  # rigid-only scene: the last dofs are the walls
    size = max(box[1] - box[0], box[3] - box[2])
    assert np.max(np.abs(q - reference.q)) <= 1e-10 * size
    assert _frames(out) == _frames(tmp_path / "ref") == list(range(reference.frame))
    assert sorted(p.name for p in (out / "frames").glob("*.vtu")) == \
        sorted(p.name for p in (tmp_path / "ref" / "frames").glob("*.vtu"))
    steps = np.loadtxt(out / "history.csv", delimiter=",", skiprows=1, usecols=1)
    assert np.array_equal(steps, np.arange(1, reference.step + 1))  # no step lost or repeated


def _history_of_steps(path: Path, steps: int) -> None:
    h = History(path, None)
    for step in range(1, steps + 1):
        h.append({k: (float(step) if k == "time" else step if k == "step" else 0.5) for k in HISTORY_COLUMNS})
    h.close()


@pytest.mark.parametrize("cut", ["159.", "159.0,3", "159.0,3,1,0.5", "\n"])
def test_resume_drops_a_history_line_cut_by_a_kill(tmp_path, cut):
    path = tmp_path / "history.csv"
    _history_of_steps(path, 158)
    with open(path, "a") as fh:
        fh.write(cut)  # a kill while the row of step 159 was being written
    History(path, resume_step=150).close()
    steps = np.loadtxt(path, delimiter=",", skiprows=1, usecols=1)
    assert np.array_equal(steps, np.arange(1, 151))


def test_resume_refuses_a_history_of_other_columns(tmp_path):
    path = tmp_path / "history.csv"
    path.write_text("time,step,phi\n1.0,1,0.8\n")
    with pytest.raises(OutputFolderError, match="history.csv.*header"):
        History(path, resume_step=1)


@pytest.mark.parametrize("missing", [1, 2])
def test_resume_keeps_a_history_of_a_previous_version(tmp_path, missing):
    """A history written before its last columns existed (hold_torque; sub_steps and hold_torque)
    is resumed: its rows are kept, their missing fields left empty (unknown), and new rows have them."""
    path = tmp_path / "history.csv"
    old = HISTORY_COLUMNS[:-missing]
    path.write_text(",".join(old) + "\n" + "".join(",".join(str(s) for _ in old) + "\n" for s in range(1, 6)))
    h = History(path, resume_step=3)
    h.append({k: 4 for k in HISTORY_COLUMNS})
    h.close()
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["step"] for r in rows] == ["1", "2", "3", "4"]
    for column in HISTORY_COLUMNS[-missing:]:
        assert [r[column] for r in rows] == ["", "", "", "4"]
    if missing == 1:
        assert [r["sub_steps"] for r in rows] == ["1", "2", "3", "4"]


def _holder(out: Path) -> subprocess.Popen:
    """Another process that holds the output folder's lock until killed."""
    code = ("import sys, time; from compute import output_folder; output_folder.acquire(sys.argv[1]); "
            "print('held', flush=True); time.sleep(600)")
    proc = subprocess.Popen([sys.executable, "-c", code, str(out)], stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == "held"
    return proc


def test_two_computes_cannot_write_one_folder(tmp_path):
    scene = _scene(tmp_path / "scene")
    out = tmp_path / "out"
    holder = _holder(out)
    try:
        second = subprocess.run([sys.executable, "-m", "compute", str(scene), "--out", str(out)],
                                capture_output=True, text=True)
        assert second.returncode == 2
        assert "locked by another process" in second.stderr and "--wait" in second.stderr
        assert sorted(p.name for p in out.iterdir()) == [".lock"]  # it wrote nothing
        waiting = subprocess.Popen([sys.executable, "-m", "compute", str(scene), "--out", str(out), "--wait"],
                                   stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        time.sleep(2.0)
        assert waiting.poll() is None and not (out / "history.csv").exists()  # waiting, not writing
    finally:
        holder.kill()
        holder.wait()
    assert waiting.wait(timeout=300) == 0, waiting.stderr.read()
    assert (out / "COMPLETE").exists() or (out / "INCOMPLETE").exists()


def test_resume_refuses_a_changed_scene(tmp_path):
    scene = _scene(tmp_path / "scene")
    out = tmp_path / "out"
    subprocess.run([sys.executable, "-m", "compute", str(scene), "--out", str(out)], check=True, capture_output=True)
    toml = scene / "scene.toml"
    toml.write_text(toml.read_text().replace("time_step = 0.1", "time_step = 0.2"))
    with pytest.raises(OutputFolderError, match=r"out/scene.toml: field 'solver.time_step'.*changed: solver.time_step"):
        run(scene, out, resume=True, log=lambda m: None)


def test_resume_after_a_kill_mid_write_removes_the_temporary_files(tmp_path):
    scene = _scene(tmp_path / "scene")
    out = tmp_path / "out"
    subprocess.run([sys.executable, "-m", "compute", str(scene), "--out", str(out)], check=True, capture_output=True)
    stale = [out / "frames" / "bodies_00099.tmp.vtu", out / "history.tmp", out / "bodies.pvd.tmp",
             out / "checkpoint" / "state.tmp.npz", out / "progress.json.tmp"]
    for path in stale:
        path.write_text("cut by a kill")
    (out / "COMPLETE").unlink(missing_ok=True)
    (out / "INCOMPLETE").unlink(missing_ok=True)
    (out / "FAILED").write_text("an earlier failure")  # resumed with a fix: its diagnosis is no longer the run's end
    run(scene, out, resume=True, log=lambda m: None)  # a frame-number parse of 'bodies_00099.tmp' failed here
    assert not any(path.exists() for path in stale) and not (out / "FAILED").exists()


def test_wall_time_checkpoints(tmp_path, monkeypatch):
    """--checkpoint-minutes adds checkpoints by wall time: with a clock that advances one minute
    per reading and a limit of half a minute, every step checkpoints; without it, only every
    checkpoint_every_steps (25) steps, at the two stage ends and at the end."""
    import compute.run as run_module
    from compute.run import Run

    scene = _scene(tmp_path / "scene")
    steps = {}
    for minutes in (None, 0.5):
        clock = iter(range(0, 10**9, 60))
        monkeypatch.setattr(run_module.time, "monotonic", lambda: float(next(clock)))
        r = Run(scene, tmp_path / f"out_{minutes}", log=lambda m: None, checkpoint_minutes=minutes)
        taken, save = [], r.checkpoint
        monkeypatch.setattr(r, "checkpoint", lambda: (taken.append(r.state.step), save()))
        n = r.execute().step
        steps[minutes] = set(taken)
    assert steps[0.5] == set(range(1, n + 1))
    every_25 = set(range(25, n + 1, 25))
    assert every_25 <= steps[None] and n in steps[None] and len(steps[None] - every_25) <= 2


def test_checkpoint_minutes_must_be_positive(tmp_path):
    from compute.run import Run

    with pytest.raises(ValueError, match="checkpoint_minutes: expected a positive number"):
        Run(_scene(tmp_path / "scene"), tmp_path / "out", checkpoint_minutes=0.0)
    cli = subprocess.run([sys.executable, "-m", "compute", str(tmp_path / "scene"), "--out", str(tmp_path / "o"),
                          "--checkpoint-minutes", "-1"], capture_output=True, text=True)
    assert cli.returncode == 2 and "--checkpoint-minutes: expected a positive number of minutes" in cli.stderr


def test_sigterm_stops_after_the_step_with_a_checkpoint(tmp_path):
    """SIGTERM: the run checkpoints at the end of its step and dies by the signal (a killed run,
    resumed by dispatch); the checkpoint and the history end at that step, and a resume goes on from it to the end of the program with no step lost or repeated."""
    scene = _scene(tmp_path / "scene")
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "compute", str(scene), "--out", str(out)]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    ckpt = out / "checkpoint" / "state.npz"
    deadline = time.time() + 120
    while time.time() < deadline and proc.poll() is None and not (ckpt.is_file() and ckpt.stat().st_size > 0):
        time.sleep(0.05)
    time.sleep(0.3)  # some steps past the first checkpoint
    assert proc.poll() is None, "the run finished before it could be stopped: make it longer"
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == -signal.SIGTERM
    with np.load(ckpt) as d:
        stopped_at = int(d["scalars"][1])
    assert f"stopped by SIGTERM after step {stopped_at}, checkpoint written" in err
    steps = np.loadtxt(out / "history.csv", delimiter=",", skiprows=1, usecols=1)
    assert np.array_equal(steps, np.arange(1, stopped_at + 1))
    assert not (out / "FAILED").exists() and not (out / "COMPLETE").exists()

    resumed = subprocess.run(cmd + ["--resume"], capture_output=True, text=True)
    assert resumed.returncode == 0, resumed.stderr
    steps = np.loadtxt(out / "history.csv", delimiter=",", skiprows=1, usecols=1)
    assert stopped_at < steps[-1] and np.array_equal(steps, np.arange(1, steps[-1] + 1))


def test_resume_from_a_history_older_than_the_checkpoint_says_which_steps_are_missing(tmp_path):
    """A history copied before the flush that precedes a checkpoint (a folder added to git while
    its run writes it) lacks the last steps before the checkpoint: the run goes on from the
    checkpoint, the log names the missing steps and summary.json counts the run's steps by number
    and lists the gap (the per-stage sums cannot include those rows)."""
    scene = _scene(tmp_path / "scene")
    out = tmp_path / "out"
    first = run(scene, out, log=lambda m: None)
    with np.load(out / "checkpoint" / "state.npz") as d:
        at = int(d["scalars"][1])
    assert at == first.step > 60
    with open(out / "history.csv", newline="") as fh:
        lines = fh.readlines()
    (out / "history.csv").write_text("".join(lines[:1 + at - 20]))  # rows 1 .. at - 20: 20 rows short
    logged = []
    resumed = run(scene, out, resume=True, log=logged.append)
    assert resumed.step == at
    assert any(f"no rows for steps {at - 19}-{at}" in m for m in logged), logged
    summary = json.loads((out / "summary.json").read_text())
    assert summary["steps"] == at and summary["history_missing_steps"] == [[at - 19, at]]
    assert sum(s["steps"] for s in summary["stages"]) == at - 20
