"""A scene or output file that cannot be read, or is not what it should be, ends in the toolkit's
input error naming the file (exit code 2), never a traceback; frames.csv is checked complete by
its end line (row count and CRC-32), and one of an earlier version (no end line) stays readable
while its last row is whole."""

from __future__ import annotations

import contextlib
import errno
import io
import os
import shutil
from pathlib import Path

import pytest

from compute.__main__ import main as compute_main
from compute.output import read_frame_rows
from post.__main__ import main as post_main
from post.frames import read_frames_table
from tests.compute.scenes import finished_rigid_run


@pytest.fixture(scope="module")
def finished(tmp_path_factory) -> tuple[Path, Path]:
    return finished_rigid_run(tmp_path_factory.mktemp("reads"))


@pytest.fixture
def out(finished, tmp_path) -> Path:
    """A copy of the finished output folder, to damage."""
    copy = tmp_path / "out"
    shutil.copytree(finished[1], copy)
    return copy


def _run(main, *args) -> tuple[int, str]:
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        code = main([str(a) for a in args])
    return code, err.getvalue()


def _refused(main, file: str, *args, field: str = "") -> str:
    code, err = _run(main, *args)
    assert code == 2 and file in err and "expected" in err and f"field '{field}" in err, err
    assert "Traceback" not in err
    return err


def test_post_refuses_a_frames_csv_of_random_bytes(out):
    (out / "frames.csv").write_bytes(bytes(range(256)) * 4)
    _refused(post_main, "frames.csv", out, field="<file>")


def test_post_refuses_a_frames_csv_cut_short(out):
    """The issue's case: the last bytes cut, a wall position 0.8684082602313874 read as
    0.86840826023 (the end line goes first, then the last row's last digits)."""
    data = (out / "frames.csv").read_bytes()
    last_row_end = data.rindex(b"\r\n#end")
    (out / "frames.csv").write_bytes(data[:last_row_end - 5])
    _refused(post_main, "frames.csv", out, field="<end line>")


def test_post_refuses_a_frames_csv_changed_in_place(out):
    text = (out / "frames.csv").read_bytes().decode()
    header, first, rest = text.split("\r\n", 2)
    time = first.split(",")[1]
    changed = first.replace(time, time.replace(time[-1], "7" if time[-1] != "7" else "8"), 1)
    (out / "frames.csv").write_bytes("\r\n".join([header, changed, rest]).encode())
    _refused(post_main, "frames.csv", out, field="<end line>")


def test_a_frames_csv_of_an_earlier_version_is_read_while_whole(out):
    """Without the end line (as written before it existed): the same records; cut mid-row: refused."""
    records = read_frames_table(out)
    text = (out / "frames.csv").read_bytes().decode()
    legacy = text[:text.index("#end")]
    (out / "frames.csv").write_bytes(legacy.encode())
    assert read_frames_table(out) == records
    (out / "frames.csv").write_bytes(legacy[:-4].encode())
    _refused(post_main, "frames.csv", out, field="<end line>")


def test_resume_rewrites_an_earlier_frames_csv_with_its_end_line(finished, out):
    text = (out / "frames.csv").read_bytes().decode()
    (out / "frames.csv").write_bytes(text[:text.index("#end")].encode())
    for marker in ("COMPLETE", "INCOMPLETE"):
        (out / marker).unlink(missing_ok=True)
    assert _run(compute_main, finished[0], "--out", out, "--resume")[0] == 0
    assert (out / "frames.csv").read_bytes() == (finished[1] / "frames.csv").read_bytes()


@pytest.mark.parametrize("name", ["checkpoint/state.npz", "history.csv", "frames.csv", "scene.toml"])
def test_resume_refuses_a_damaged_output_file(finished, out, name):
    (out / name).write_bytes(b"\xff\xfe garbage \x00" * 10)
    _refused(compute_main, name, finished[0], "--out", out, "--resume")


def test_resume_refuses_a_frames_csv_missing_rows_the_checkpoint_wrote(finished, out):
    rows = read_frame_rows(out / "frames.csv")
    from compute.output import write_frame_rows

    write_frame_rows(out / "frames.csv", rows[:-1])  # a consistent file, but a frame short
    _refused(compute_main, "frames.csv", finished[0], "--out", out, "--resume", field="frame")


def _unsearchable(monkeypatch, folder: Path) -> None:
    """Every stat below ``folder`` fails with EACCES, as for a folder of mode 000 (simulated:
    the tests may run as root, whom permissions do not stop)."""
    real = Path.stat

    def stat(self, *a, **k):
        if self.is_relative_to(folder) and self != folder:
            raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), str(self))
        return real(self, *a, **k)

    monkeypatch.setattr(Path, "stat", stat)


def test_a_scene_folder_that_cannot_be_searched(finished, tmp_path, monkeypatch):
    _unsearchable(monkeypatch, finished[0])
    err = _refused(compute_main, "scene.toml", finished[0], "--out", tmp_path / "new", field="<file>")
    assert "Permission denied" in err


def test_an_output_folder_that_cannot_be_searched(out, monkeypatch):
    _unsearchable(monkeypatch, out)
    err = _refused(post_main, "frames.csv", out, field="<file>")
    assert "Permission denied" in err


def test_a_real_unreadable_scene_folder(finished, tmp_path):
    if os.geteuid() == 0:
        pytest.skip("root reads folders of mode 000; test_a_scene_folder_that_cannot_be_searched simulates it")
    scene = tmp_path / "scene"
    shutil.copytree(finished[0], scene)
    os.chmod(scene, 0)
    try:
        _refused(compute_main, "scene.toml", scene, "--out", tmp_path / "new")
    finally:
        os.chmod(scene, 0o700)
