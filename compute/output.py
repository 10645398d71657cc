"""Output folder: VTK frames (bodies, contacts, walls), .pvd collections, frames.csv, history.csv.

See docs/FORMATS.md. Every file is written through :mod:`compute.files`: whole files atomically
(temporary file, then rename), so that a run killed mid-write leaves only complete files, and
an operating-system refusal (full disk, permission) is an OutputWriteError naming the file; the
.pvd files are regenerated from frames.csv.

frames.csv ends with a line written last, ``#end rows=N crc32=XXXXXXXX``: the number of frame
rows and the CRC-32 of every byte before that line. Why: a copy cut short, or a file damaged in
place, otherwise parses as valid rows with wrong numbers (a wall position cut from
0.8684082602313874 to 0.86840826023). A frames.csv of an earlier version has no end line; it
is read when its last row is complete (ends with its line break), and a run resumed from it
rewrites it with one.
"""

from __future__ import annotations

import csv
import io
import os
import zlib
from pathlib import Path

import numpy as np

from compute import files
from compute.bodies_io import VTU_COMPRESSION
from compute.contact.rows import ContactRows
from compute.errors import InputError, OutputFolderError

FRAME_COLUMNS = ["frame", "time", "step", "stage", "pressure_applied", "equilibrated",
                 "xmin", "xmax", "ymin", "ymax"]
HISTORY_COLUMNS = ["time", "step", "stage", "pressure_applied", "xmin", "xmax", "ymin", "ymax", "phi",
                   "nlgs_sweeps", "nlgs_residual", "kinetic_energy", "inertial_number", "n_contacts",
                   "max_penetration", "newton_iterations", "cuts", "load_halvings", "sub_steps", "hold_torque"]
ADDED_COLUMNS = 2  # trailing columns that histories of earlier versions lack (resumed: left empty, unknown)
SERIES = ("bodies", "contacts", "walls")
CHECKPOINT = "checkpoint/state.npz"  # the restart point, relative to the output folder
END_MARK = "#end"  # first word of the last line of frames.csv (module docstring)


def _atomic_write_mesh(path: Path, mesh) -> None:
    import meshio

    files.write_atomic(path, lambda tmp: meshio.write(tmp, mesh, file_format="vtu", binary=True,
                                                      compression=VTU_COMPRESSION))


def frame_path(out: str | Path, series: str, frame: int) -> Path:
    """``OUT/frames/{series}_NNNNN.vtu``, ``series`` one of SERIES (bodies, contacts, walls)."""
    return Path(out) / "frames" / f"{series}_{frame:05d}.vtu"


def remove_temporaries(out: str | Path) -> None:
    """Delete what an interrupted atomic write left behind: every file is written to a
    temporary name (``NAME.tmp.EXT``, compute.files.temporary), then renamed; ``*.tmp`` are the
    temporary names of earlier versions."""
    for pattern in ("*.tmp", "*.tmp.*", "frames/*.tmp.*", "checkpoint/*.tmp.*"):
        for path in Path(out).glob(pattern):
            files.remove(path)


def frame_files(out: str | Path) -> dict[Path, int]:
    """Every frame file of OUT/frames (the three series) and its frame number."""
    files = {}
    for series in SERIES:
        for path in (Path(out) / "frames").glob(f"{series}_*.vtu"):
            number = path.stem[len(series) + 1:]
            if number.isdigit():
                files[path] = int(number)
    return files


def write_contacts(path: Path, contacts: ContactRows, centres_i: np.ndarray, centres_j: np.ndarray,
                   time_step: float) -> None:
    """Active contacts (r_n > 0) as lines from centre i to centre j (or the wall contact point).

    centres_i, centres_j (nc, 2): the end points of each contact's line; forces of the impulses
    over the time step ``time_step`` (:meth:`ContactRows.forces`).
    """
    import meshio

    act = contacts.impulse[:, 0] > 0.0
    n = int(act.sum())
    z = np.zeros((n, 1))
    pts = np.concatenate([np.hstack([centres_i[act], z]), np.hstack([centres_j[act], z])])
    lines = np.column_stack([np.arange(n), n + np.arange(n)])
    nrm = contacts.normal[act]
    tan = np.column_stack([-nrm[:, 1], nrm[:, 0]])
    forces = contacts.forces(time_step)[act]
    fn, ft = forces[:, 0], forces[:, 1]
    force = fn[:, None] * nrm + ft[:, None] * tan
    data = {
        "body_i": contacts.body_i[act], "body_j": contacts.body_j[act],
        "normal": np.hstack([nrm, z]), "force": np.hstack([force, z]), "fn": fn, "ft": ft,
        "gap": contacts.gap[act], "branch": np.hstack([contacts.branch[act], z]),
        "contact_point": np.hstack([contacts.point[act], z]),
    }
    _atomic_write_mesh(path, meshio.Mesh(pts, [("line", lines)], cell_data={k: [v] for k, v in data.items()}))


def write_walls(path: Path, bounds: np.ndarray, force: np.ndarray, pressure: float,
                velocity: np.ndarray) -> None:
    """The four walls as lines; ``force`` (4,) the normal force particles exert on each wall."""
    import meshio

    x0, x1, y0, y1 = bounds
    pts = np.array([[x0, y0, 0], [x1, y0, 0], [x1, y1, 0], [x0, y1, 0]], float)
    lines = np.array([[3, 0], [1, 2], [0, 1], [2, 3]])  # left, right, bottom, top
    lengths = np.array([y1 - y0, y1 - y0, x1 - x0, x1 - x0])
    data = {"wall": np.array([-1, -2, -3, -4]), "position": np.asarray(bounds, float), "length": lengths,
            "force": np.asarray(force, float), "pressure_applied": np.full(4, pressure),
            "velocity": np.asarray(velocity, float)}
    _atomic_write_mesh(path, meshio.Mesh(pts, [("line", lines)], cell_data={k: [v] for k, v in data.items()}))


def write_pvd(out: Path, rows: list[dict]) -> None:
    """Regenerate the three .pvd collections from the frame rows."""
    for series in SERIES:
        lines = ['<?xml version="1.0"?>',
                 '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">', "  <Collection>"]
        for r in rows:
            f = int(r["frame"])
            lines.append(f'    <DataSet timestep="{float(r["time"])!r}" group="" part="0" '
                         f'file="{frame_path("", series, f).as_posix()}"/>')
        lines += ["  </Collection>", "</VTKFile>", ""]
        files.write_text(out / f"{series}.pvd", "\n".join(lines))


def _csv_text(columns: list[str], rows: list[dict]) -> str:
    stream = io.StringIO()
    w = csv.DictWriter(stream, fieldnames=columns)
    w.writeheader()
    w.writerows(rows)
    return stream.getvalue()


def read_csv_rows(path: Path, error: type[InputError] = OutputFolderError) -> list[dict]:
    """The rows of a CSV file of the output folder (none when it does not exist); an unreadable
    file raises ``error`` naming it."""
    if not files.is_file(path, error):
        return []
    try:
        return list(csv.DictReader(io.StringIO(files.read_text(path, error))))
    except csv.Error as exc:
        raise error(path, "<file>", "CSV text", str(exc)) from None


def write_csv_rows(path: Path, columns: list[str], rows: list[dict]) -> None:
    files.write_text(path, _csv_text(columns, rows))


def _end_line(body: str, rows: int) -> str:
    return f"{END_MARK} rows={rows} crc32={zlib.crc32(body.encode('utf-8')):08x}\r\n"


def write_frame_rows(path: Path, rows: list[dict]) -> None:
    """frames.csv: the header, one row per frame, and the end line (module docstring)."""
    body = _csv_text(FRAME_COLUMNS, rows)
    files.write_text(path, body + _end_line(body, len(rows)))


def read_frame_rows(path: Path, error: type[InputError] = OutputFolderError) -> list[dict]:
    """The rows of a frames.csv (none when it does not exist), checked complete: its end line's
    row count and CRC-32 (module docstring), or, in a file of an earlier version without one, a
    last row ended by its line break. Raises ``error`` naming the file otherwise."""
    if not files.is_file(path, error):
        return []
    text = files.read_text(path, error)
    body, _, last = text.rstrip("\r\n").rpartition("\n")
    body = body + "\n" if body else ""
    if last.startswith(END_MARK):
        try:
            rows = list(csv.DictReader(io.StringIO(body)))
        except csv.Error as exc:
            raise error(path, "<file>", "CSV text", str(exc)) from None
        if text != body + _end_line(body, len(rows)):
            raise error(path, "<end line>", f"'{_end_line(body, len(rows)).strip()}': the count and CRC-32 of "
                        "the rows above it (the file was changed or damaged after it was written)", last)
        return rows
    if text and not text.endswith("\n"):
        raise error(path, "<end line>", f"a last line '{END_MARK} rows=N crc32=...' written after the rows "
                    "(the file was cut short: its last row is incomplete)", text.splitlines()[-1])
    return read_csv_rows(path, error)


class History:
    """Per-step history rows, appended to ``history.csv`` and flushed at checkpoints.

    ``missing``: the ranges [first, last] of steps up to the resume step that have no row (a
    history copied while its run was writing it, older than the checkpoint beside it); the run
    goes on from the checkpoint all the same, and says so."""

    def __init__(self, path: Path, resume_step: int | None):
        self.path = path
        self.missing: list[tuple[int, int]] = []
        rows = []
        if resume_step is not None and files.is_file(path, OutputFolderError):
            rows = rows_up_to_step(path, resume_step)
            self.missing = missing_steps([int(r["step"]) for r in rows], resume_step)
        write_csv_rows(path, HISTORY_COLUMNS, rows)
        with files.guarded(path):
            self.fh = open(path, "a", newline="")
        self.writer = csv.writer(self.fh)

    def append(self, row: dict) -> None:
        with files.guarded(self.path):
            self.writer.writerow([_fmt(row[k]) for k in HISTORY_COLUMNS])

    def flush(self) -> None:
        with files.guarded(self.path):
            self.fh.flush()
            os.fsync(self.fh.fileno())

    def close(self) -> None:
        with files.guarded(self.path):
            self.fh.close()


def rows_up_to_step(path: Path, step: int) -> list[dict]:
    """The history rows of steps 1..``step``: what a checkpoint at ``step`` had flushed.

    Rows are flushed to disk before each checkpoint, so every row up to the checkpoint's step is
    complete; whatever follows it (rows of steps after the checkpoint, possibly a last line cut by a
    kill, such as ``159.`` or ``159.0,3``) is dropped, however it parses.
    """
    rows = []
    try:
        lines = list(csv.reader(io.StringIO(files.read_text(path, OutputFolderError))))
    except csv.Error as exc:
        raise OutputFolderError(path, "<file>", "CSV text", str(exc)) from None
    header = lines[0] if lines else []
    n = len(header)
    if n < len(HISTORY_COLUMNS) - ADDED_COLUMNS or header != HISTORY_COLUMNS[:n]:
        raise OutputFolderError(path, "header", "the history columns of this version (" + ",".join(HISTORY_COLUMNS)
                                + "); run again without --resume", header)
    for fields in lines[1:]:
        row = dict(zip(HISTORY_COLUMNS, fields + [""] * (len(HISTORY_COLUMNS) - n)))
        if len(fields) != n or not row["step"].isdigit() or int(row["step"]) > step:
            break
        rows.append(row)
        if int(row["step"]) == step:
            break
    return rows


def missing_steps(steps: list[int], last: int) -> list[tuple[int, int]]:
    """Ranges [first, last] (inclusive) of the steps 1..``last`` absent from the increasing
    ``steps``."""
    gaps, expected = [], 1
    for s in [*steps, last + 1]:
        if s > expected:
            gaps.append((expected, s - 1))
        expected = max(expected, s + 1)
    return gaps


def _fmt(x) -> str:
    return repr(float(x)) if isinstance(x, (float, np.floating)) else str(x)
