"""studies.dispatch: independent runs on a local Dask cluster; a failing run does not take the
others down and records its diagnosis; complete runs are skipped when dispatching again."""

import json

import numpy as np
import pytest

from compute.summary import run_status
from studies.dispatch import RunSpec, dispatch, run_times


def lattice_scene(folder, pressures=(1.0,)):
    """3 x 3 touching rigid disks in their box: equilibrated within a few checks."""
    from pre.scene import default_parameters, write_scene

    xy = np.stack(np.meshgrid(np.arange(3) + 0.5, np.arange(3) + 0.5), -1).reshape(-1, 2)
    params = default_parameters((0.0, 3.0, 0.0, 3.0), 0.3, 1.0, list(pressures))
    return write_scene(folder, params, xy, np.full(9, 0.5), ["rigid"] * 9)


def test_failure_isolated_and_complete_runs_skipped(tmp_path):
    good = lattice_scene(tmp_path / "good" / "scene")
    bad = lattice_scene(tmp_path / "bad" / "scene")
    (bad / "scene.toml").write_text((bad / "scene.toml").read_text().replace("time_step = ", "time_step = -"))
    runs = [RunSpec("bad", bad, tmp_path / "bad" / "out"), RunSpec("good", good, tmp_path / "good" / "out")]
    log = tmp_path / "dispatch.jsonl"
    results = dispatch(runs, n_workers=2, log=None, log_file=log, checkpoint_minutes=30.0)  # reaches the child
    assert [(r.name, r.status) for r in results] == [("bad", "failed"), ("good", "complete")]
    assert "solver.time_step" in (tmp_path / "bad" / "out" / "FAILED").read_text()
    assert run_status(tmp_path / "good" / "out") == "complete"
    assert "equilibrated" in (tmp_path / "good" / "out" / "compute.log").read_text()
    # peak memory of the run process from the kernel: a Python with numpy, scipy and numba loaded
    # holds well over 60 MiB, a 9-disk run well under 2 GiB
    assert 60 < results[1].peak_mib < 2048 and results[1].wall_time > 0

    again = dispatch(runs, log=None, log_file=log)  # no cluster needed: nothing to run
    assert [(r.name, r.status) for r in again] == [("bad", "failed"), ("good", "skipped")]
    entries = [json.loads(line) for line in log.read_text().splitlines()]
    assert [(e["name"], e["status"]) for e in entries][-2:] == [("bad", "failed"), ("good", "skipped")]
    assert entries[1]["peak_mib"] == results[1].peak_mib and entries[-1]["peak_mib"] == 0.0


def test_names_must_be_unique(tmp_path):
    with pytest.raises(ValueError, match="unique"):
        dispatch([RunSpec("a", tmp_path, tmp_path / "1"), RunSpec("a", tmp_path, tmp_path / "2")], log=None)


def test_progress_of_the_runs_in_plain_lines(tmp_path):
    import io

    from compute.progress import Display

    runs = [RunSpec(f"r{k}", lattice_scene(tmp_path / f"r{k}" / "scene", pressures=(1.0, 2.0)), tmp_path / f"r{k}" / "out")
            for k in range(2)]
    stream = io.StringIO()
    shown = Display(2, "study", stream=stream, interactive=False, interval=0.0)
    results = dispatch(runs, n_workers=2, log=None, progress=shown)
    assert all(r.status == "complete" for r in results)
    lines = stream.getvalue().splitlines()
    assert all(line.startswith("study: ") for line in lines) and lines[-1] == "study: 2/2 runs ended"
    assert any("runs ended;" in line for line in lines)  # one line per look at the running runs
    for r in runs:
        assert json.loads((r.out / "progress.json").read_text())["status"] == "complete"


def test_run_times_sum_the_dispatches_of_a_run(tmp_path):
    log = tmp_path / "dispatch.jsonl"
    log.write_text("\n".join(json.dumps(e) for e in [
        {"name": "a", "status": "killed", "wall_time": 10.0}, {"name": "a", "status": "complete", "wall_time": 5.0},
        {"name": "b", "status": "skipped", "wall_time": 0.0}, {"name": "b", "status": "failed", "wall_time": 2.0}]))
    assert run_times(log) == {"a": 15.0, "b": 2.0}
    assert run_times(tmp_path / "none.jsonl") == {}


def test_local_cluster_workers_run_with_dask_monitoring_slowed():
    """The workers of studies.dispatch.local_cluster carry QUIET (no profiler sampling their
    threads, slow monitors), and the caller's Dask configuration is left as it was."""
    import dask
    from dask.distributed import Client

    from studies.dispatch import QUIET, local_cluster

    before = {key: dask.config.get(key) for key in QUIET}
    with local_cluster(2) as cluster, Client(cluster) as client:
        seen = client.run(lambda: {key: dask.config.get(key) for key in QUIET})
    assert len(seen) == 2 and all(config == QUIET for config in seen.values())
    assert {key: dask.config.get(key) for key in QUIET} == before != QUIET


def test_runs_do_not_inherit_the_workers_malloc_setting():
    """A Dask worker runs with MALLOC_TRIM_THRESHOLD_ set (its nanny's default), which turns off
    glibc's dynamic mmap threshold; a run started by it gets the environment without it, and the
    threads it was given."""
    import os

    from dask.distributed import Client

    from studies.dispatch import child_environment, local_cluster

    with local_cluster(1) as cluster, Client(cluster) as client:
        worker, child = client.submit(lambda: (dict(os.environ), child_environment(1))).result()
    assert "MALLOC_TRIM_THRESHOLD_" in worker
    assert "MALLOC_TRIM_THRESHOLD_" not in child and child["OMP_NUM_THREADS"] == "1"


def test_a_signal_stops_the_study_after_the_running_runs_step(tmp_path):
    """SIGTERM to the dispatching process: the queued run is not started; the running one is asked
    by OUT/STOP to stop after its step, checkpoints and dies by SIGTERM, recorded as killed with
    its wall time; the STOP file is gone, so that the next dispatch resumes it."""
    import os
    import signal
    import threading
    import time

    from pre.scene import default_parameters, write_scene

    xy = np.stack(np.meshgrid(np.arange(3) + 0.5, np.arange(3) + 0.5), -1).reshape(-1, 2)
    params = default_parameters((0.0, 3.0, 0.0, 3.0), 0.3, 1.0, [1.0])
    # walls held still for a time no run reaches: no stage-end test that a lattice at rest could
    # pass (with tolerances alone it did, its velocities exactly zero on some installations)
    params["walls"]["control"] = "velocity"
    del params["loading"]["pressures"]
    params["loading"].update(velocity=0.0, duration=1e12)
    endless = write_scene(tmp_path / "endless" / "scene", params, xy, np.full(9, 0.5), ["rigid"] * 9)
    queued = lattice_scene(tmp_path / "queued" / "scene")
    out = tmp_path / "endless" / "out"
    runs = [RunSpec("endless", endless, out), RunSpec("queued", queued, tmp_path / "queued" / "out")]

    def signal_once_stepping():
        deadline = time.monotonic() + 300
        while not (out / "progress.json").is_file() and time.monotonic() < deadline:
            time.sleep(0.1)
        os.kill(os.getpid(), signal.SIGTERM)

    threading.Thread(target=signal_once_stepping, daemon=True).start()
    log = tmp_path / "dispatch.jsonl"
    results = dispatch(runs, n_workers=1, log=None, log_file=log, progress=False)
    assert [(r.name, r.status) for r in results] == [("endless", "killed"), ("queued", "not started")]
    assert results[0].wall_time > 0 and run_times(log)["endless"] == pytest.approx(results[0].wall_time)
    assert not (tmp_path / "queued" / "out").exists()
    assert (out / "checkpoint").is_dir() and not (out / "STOP").exists()
    assert "stopped by OUT/STOP after step" in (out / "compute.log").read_text()
    assert signal.getsignal(signal.SIGTERM) == signal.SIG_DFL  # the dispatcher gave it back
