"""A file the operating system refuses to write (full disk, permission, read-only file system)
stops the run FAILED with a one-line diagnosis naming the file and the error, exit code 4, what
was written before kept and no temporary file left; once the cause is gone, --resume ends the run
exactly as an uninterrupted one. The faults are simulated at the OS boundary (os.replace, the
rename that ends every whole-file write, and os.fsync, which flushes the history), since a real
full disk cannot be made in a test."""

from __future__ import annotations

import contextlib
import errno
import io
import os
from pathlib import Path

import pytest

from compute.__main__ import main
from tests.compute.scenes import small_rigid_scene


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> tuple[Path, Path]:
    folder = tmp_path_factory.mktemp("faults")
    scene = small_rigid_scene(folder / "scene")
    assert _main(scene, folder / "ref")[0] == 0
    return scene, folder / "ref"


def _main(scene: Path, out: Path, *extra: str) -> tuple[int, str]:
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        code = main([str(scene), "--out", str(out), *extra])
    return code, err.getvalue()


def _refuse(monkeypatch, name: str, nth: int, code: int) -> None:
    """The ``nth`` whole-file write of a file called ``name`` (and every later one) fails with
    ``code``; "history.csv": its ``nth`` flush."""
    real_replace, real_fsync = os.replace, os.fsync
    seen = {"n": 0}

    def hit() -> None:
        seen["n"] += 1
        if seen["n"] >= nth:
            raise OSError(code, os.strerror(code))

    def replace(src, dst, *a, **k):
        if Path(dst).name == name:
            hit()
        return real_replace(src, dst, *a, **k)

    def fsync(fd):
        if name == "history.csv":
            hit()
        return real_fsync(fd)

    monkeypatch.setattr(os, "replace", replace)
    monkeypatch.setattr(os, "fsync", fsync)


@pytest.mark.parametrize("name, nth, code", [
    ("progress.json", 2, errno.ENOSPC),    # the write of the issue: the first stage's end
    ("state.npz", 3, errno.ENOSPC),        # a checkpoint
    ("bodies_00001.vtu", 1, errno.EROFS),  # a frame
    ("frames.csv", 2, errno.EACCES),
    ("history.csv", 4, errno.ENOSPC),
])
def test_a_refused_write_fails_the_run_with_a_diagnosis_and_resume_finishes_it(reference, tmp_path, monkeypatch,
                                                                                 name, nth, code):
    scene, ref = reference
    out = tmp_path / "out"
    with monkeypatch.context() as m:
        _refuse(m, name, nth, code)
        status, err = _main(scene, out)
    assert status == 4, err
    reason = os.strerror(code)
    failed = (out / "FAILED").read_text()
    assert failed.count("\n") == 1 and name in failed and reason in failed, failed
    assert name in err and reason in err and "Traceback" not in err, err
    assert not [p for p in out.rglob("*") if ".tmp" in p.name]
    assert (out / "checkpoint" / "state.npz").is_file() and not (out / "COMPLETE").exists()

    status, err = _main(scene, out, "--resume")
    assert status == 0, err
    assert not (out / "FAILED").exists()
    for f in ("history.csv", "frames.csv", "summary.json", *(f"frames/{p.name}" for p in (ref / "frames").iterdir())):
        assert (out / f).read_bytes() == (ref / f).read_bytes(), f


def test_a_folder_that_refuses_every_write_fails_without_a_traceback(reference, tmp_path, monkeypatch):
    """Nothing can be written, FAILED included: the diagnosis goes to stderr, exit code 4."""
    scene, _ = reference
    real = os.replace

    def refused(src, dst, *a, **k):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(os, "replace", refused)
    status, err = _main(scene, tmp_path / "out")
    monkeypatch.setattr(os, "replace", real)
    assert status == 4, err
    assert "scene.toml: could not be written: [Errno 28] No space left on device" in err and "Traceback" not in err
    assert not (tmp_path / "out" / "FAILED").exists()
    assert not [p for p in (tmp_path / "out").rglob("*") if ".tmp" in p.name]


def test_a_real_read_only_folder(reference, tmp_path):
    """Where permissions apply (not as root): a run into a folder made read-only mid-way."""
    if os.geteuid() == 0:
        pytest.skip("root writes into read-only folders; test_a_refused_write_... simulates EACCES")
    scene, _ = reference
    out = tmp_path / "out"
    assert _main(scene, out)[0] == 0
    (out / "COMPLETE").unlink()
    os.chmod(out, 0o500)
    try:
        status, err = _main(scene, out, "--resume")
    finally:
        os.chmod(out, 0o700)
    assert status in (2, 4) and str(out) in err and "Traceback" not in err, err
