"""Progress of a run: plain lines in a log (the mode a log file gets), progress.json for watchers."""

import io
import json
import subprocess
import sys

from compute.progress import Display, RunProgress, read_progress
from tests.compute.test_restart import _scene


def test_plain_lines_at_most_one_per_interval_plus_marks(monkeypatch):
    clock = iter(range(0, 1000, 10))  # 10 s between two calls of the clock
    monkeypatch.setattr("compute.progress.time.monotonic", lambda: float(next(clock)))
    stream = io.StringIO()
    d = Display(5, "run", stream=stream, interactive=False, interval=25.0)
    for k in range(6):
        d.update(k, f"update {k}")
    d.mark("the end")
    lines = stream.getvalue().splitlines()
    # clock 0, 10, 20, ...: a line at 0, then the first update at least 25 s after it (30), then 60
    assert lines == ["run: update 0", "run: update 3", "run: the end"]
    assert "\r" not in stream.getvalue()


def test_run_progress_text_and_file(tmp_path, monkeypatch):
    now = [0.0]
    monkeypatch.setattr("compute.progress.time.monotonic", lambda: now[0])
    stream = io.StringIO()
    p = RunProgress(tmp_path, 3, Display(3, "compute", stream=stream, interactive=False, interval=0.0), interval=0.0)
    now[0] = 10.0
    p.step(0, 0.01, 0.81, 1, 1)  # no stage finished yet: no ETA
    assert p.text().startswith("stage 1/3 P 0.01 phi 0.81000 step 1 ") and p.text().endswith("ETA ?")
    now[0] = 40.0
    p.stage_done()  # the first stage took 40 s
    now[0] = 50.0
    p.step(1, 0.1, 0.85, 2, 1)  # two stages left, at 40 s each
    assert p.record["eta"] == 80.0 and p.text().endswith("ETA 1:20")
    assert read_progress(tmp_path) == json.loads((tmp_path / "progress.json").read_text()) == p.record
    p.finish("complete")
    assert read_progress(tmp_path)["status"] == "complete"
    assert stream.getvalue().splitlines()[-1].endswith("[complete]")


def test_compute_prints_plain_progress_lines_into_a_log(tmp_path):
    scene = _scene(tmp_path / "scene")
    log = tmp_path / "compute.log"
    with log.open("w") as stream:
        subprocess.run([sys.executable, "-m", "compute", str(scene), "--out", str(tmp_path / "out")],
                       stdout=stream, stderr=subprocess.STDOUT, check=True)
    lines = log.read_text().splitlines()
    progress = [line for line in lines if line.startswith("compute: stage ")]
    assert progress[0].startswith("compute: stage 1/2 P 1 ")  # the first step is always shown
    status = read_progress(tmp_path / "out")["status"]
    assert (tmp_path / "out" / status.upper()).is_file()  # the end status is the run's marker
    assert progress[-1].startswith("compute: stage 2/2 P 2 ") and progress[-1].endswith(f"[{status}]")
    assert "\r" not in log.read_text() and "\x1b" not in log.read_text()
