"""The output folder of a run: created before anything is written, and held by one writer.

A run takes an exclusive ``fcntl.flock`` on ``OUT/.lock`` for as long as it writes: a second
compute on the same folder refuses with :class:`~compute.errors.OutputFolderError` (or waits for
the first with ``wait=True``). The lock is released by the kernel when its holder exits, killed
or not, so a stale lock file never blocks a resume. Within one process the lock is re-entrant
(the study dispatcher's child holds it around the run it starts).
"""

from __future__ import annotations

import fcntl
import os
from pathlib import Path

from compute.errors import OutputFolderError

LOCK = ".lock"
_HELD: dict[Path, list] = {}  # folder -> [open lock file, holders in this process]


def acquire(out: str | Path, wait: bool = False) -> Path:
    """Create ``out`` if needed and take its lock; returns the resolved folder (pass it to
    :func:`release`). Raises OutputFolderError naming the folder."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise OutputFolderError(out, "--out", "an output folder", "an existing file")
    try:
        out.mkdir(parents=True, exist_ok=True)
        key = out.resolve()
        if key in _HELD:
            _HELD[key][1] += 1
            return key
        fh = open(key / LOCK, "a")
    except OSError as exc:
        raise OutputFolderError(out, "--out", "a folder this user can create and write in",
                                f"{type(exc).__name__}: {exc.strerror or exc}") from None
    try:
        fcntl.flock(fh, fcntl.LOCK_EX | (0 if wait else fcntl.LOCK_NB))
    except BlockingIOError:
        fh.close()
        raise OutputFolderError(out, "--out", "a folder no other compute is writing (use --wait to wait for it)",
                                "locked by another process") from None
    if not os.access(key, os.W_OK):
        fh.close()
        raise OutputFolderError(out, "--out", "a writable folder", "read-only")
    _HELD[key] = [fh, 1]
    return key


def release(key: Path) -> None:
    """Give back one hold of the lock taken by :func:`acquire`."""
    held = _HELD.get(key)
    if held is None:
        return
    held[1] -= 1
    if held[1] == 0:
        del _HELD[key]
        held[0].close()  # closing the file releases the flock
