"""Reading and writing files: what the operating system refuses becomes one error naming the file.

Every file compute writes into an output folder, and every scene or output file the stages
read, goes through these functions, so that a full disk, a permission, a read-only file system
or a file that is not what it should be (random bytes) ends in the toolkit's own error, with
the file and the reason, instead of a traceback:

- writing: :class:`~compute.errors.OutputWriteError` (compute.run turns it into a FAILED
  status; ``python -m compute`` exits with code 4). A whole file is written to a temporary
  name beside it (``NAME.tmp.EXT``, :func:`temporary`) and renamed over it, so a reader never
  sees half a file; when the write fails the temporary file is removed and the file keeps its
  previous content;
- reading: the caller's :class:`~compute.errors.InputError` (SceneError for a scene,
  OutputFolderError or post's OutputError for an output folder) with field ``<file>``.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

from compute.errors import InputError, OutputWriteError


def _reason(exc: OSError) -> str:
    """'[Errno 28] No space left on device' (without the file name the caller states)."""
    return f"[Errno {exc.errno}] {exc.strerror}" if exc.errno is not None else f"{type(exc).__name__}: {exc}"


# --- writing -------------------------------------------------------------------------------------
def temporary(path: str | Path) -> Path:
    """The temporary name a whole-file write of ``path`` goes through: ``NAME.tmp.EXT`` beside
    it (the extension kept: meshio and numpy choose the format by it)."""
    path = Path(path)
    return path.with_name(f"{path.stem}.tmp{path.suffix}")


@contextmanager
def guarded(path: str | Path) -> Iterator[None]:
    """Any OSError in the block is a failure to write ``path`` (appends, flushes, folders)."""
    try:
        yield
    except OSError as exc:
        raise OutputWriteError(path, _reason(exc)) from None


def write_atomic(path: str | Path, write: Callable[[Path], None]) -> None:
    """``write(tmp)`` writes the whole content to the temporary name, which then replaces
    ``path``; on an OSError the temporary file is removed and OutputWriteError raised."""
    path = Path(path)
    tmp = temporary(path)
    try:
        write(tmp)
        os.replace(tmp, path)
    except OSError as exc:
        try:
            tmp.unlink(missing_ok=True)
        except OSError:
            pass  # the folder itself refuses: nothing of ours can be in it
        raise OutputWriteError(path, _reason(exc)) from None


def write_text(path: str | Path, text: str) -> None:
    """``text`` as the whole content of ``path`` (UTF-8, written as given: no newline
    translation), atomically."""
    write_atomic(path, lambda tmp: tmp.write_bytes(text.encode("utf-8")))


def remove(path: str | Path) -> None:
    """Delete ``path`` if it exists."""
    with guarded(path):
        Path(path).unlink(missing_ok=True)


# --- reading -------------------------------------------------------------------------------------
def is_file(path: str | Path, error: type[InputError]) -> bool:
    """Whether ``path`` is a file; a folder on the way that cannot be searched (no permission)
    raises ``error`` naming it instead of answering False or a traceback."""
    try:
        return Path(path).stat().st_mode & 0o170000 == 0o100000
    except (FileNotFoundError, NotADirectoryError):
        return False
    except OSError as exc:
        raise error(path, "<file>", "a file this user can reach", _reason(exc)) from None


def read_bytes(path: str | Path, error: type[InputError]) -> bytes:
    """The content of ``path``; a missing or unreadable file raises ``error`` naming it."""
    try:
        return Path(path).read_bytes()
    except FileNotFoundError:
        raise error(path, "<file>", "an existing file") from None
    except OSError as exc:
        raise error(path, "<file>", "a file this user can read", _reason(exc)) from None


def read_text(path: str | Path, error: type[InputError]) -> str:
    """The UTF-8 text of ``path`` as stored (line ends untranslated); a missing or unreadable
    file, or bytes that are not UTF-8 text, raise ``error`` naming it."""
    data = read_bytes(path, error)
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise error(path, "<file>", "UTF-8 text", f"byte {exc.start}: {exc.reason}") from None
    if "\x00" in text:
        raise error(path, "<file>", "text (no NUL bytes)", f"a NUL byte at {text.index(chr(0))}")
    return text
