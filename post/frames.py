"""Reading an output folder (docs/FORMATS.md, "Output folder") with meshio.

Post reads only files: ``frames.csv`` and, for each of its rows, ``frames/bodies_NNNNN.vtu``,
``frames/contacts_NNNNN.vtu`` and ``frames/walls_NNNNN.vtu``. Every reader validates the fields
it uses and raises :class:`post.errors.OutputError` naming the file, the field and what was
expected (an unreadable file, or a frames.csv cut short or changed after it was written,
included). Vectors are returned with 2 components (the z = 0 component written to VTK is dropped).

A frame with no contact candidates may be a VTU piece with no cells, which meshio cannot read;
it is recognised from the piece header and read as zero contacts.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from compute.bodies_io import CELL_ELEMENT, read_layout
from compute import files
from compute.output import FRAME_COLUMNS, frame_path, read_frame_rows  # the output layout is written by compute, once
from compute.vtu_io import cell_field, read_vtu
from post.errors import OutputError

WALL_IDS = (-1, -2, -3, -4)  # left (x = xmin), right (x = xmax), bottom (y = ymin), top (y = ymax)
_BOOLEANS = {"1": True, "true": True, "0": False, "false": False}


@dataclass(frozen=True)
class FrameRecord:
    """One row of ``frames.csv``; ``box`` is (xmin, xmax, ymin, ymax)."""

    frame: int
    time: float
    step: int
    stage: int
    pressure_applied: float
    equilibrated: bool
    box: tuple[float, float, float, float]


@dataclass(frozen=True)
class MeshBlock:
    """The triangles of deformable bodies of one element type.

    ``cells`` (n_cells, 3 | 6) indexes ``Bodies.points`` in VTK node order (corners, then the
    mid-side nodes of edges 01, 12, 20 for T6); ``body`` (n_cells,) is the body id of each cell;
    ``pressure`` (n_cells,) the 2D mean stress of each cell, compression positive.
    """

    element: str
    cells: np.ndarray
    body: np.ndarray
    pressure: np.ndarray


@dataclass(frozen=True)
class Bodies:
    """The bodies of a frame in their current configuration.

    ``points`` (n_points, 2); ``radius`` (N,) nominal radii; ``rigid`` (N,) bool;
    ``rigid_ids`` (n_rigid,) and ``rigid_centres`` (n_rigid, 2); ``meshes`` the triangle blocks.
    """

    points: np.ndarray
    radius: np.ndarray
    rigid: np.ndarray
    rigid_ids: np.ndarray
    rigid_centres: np.ndarray
    meshes: tuple[MeshBlock, ...]

    @property
    def n_bodies(self) -> int:
        return len(self.radius)


@dataclass(frozen=True)
class FrameContacts:
    """Contact candidates of a frame, one row per candidate (M rows).

    ``body_i``, ``body_j`` (M,) int, ``body_j < 0`` for a wall; ``force`` (M, 2) the force exerted
    by i on j; ``fn`` (M,) its normal component (compressive >= 0); ``branch`` (M, 2) x_j - x_i
    (contact point - x_i for a wall); ``segments`` (M, 2, 2) the line from the centre of i to the
    centre of j (to the contact point for a wall).
    """

    body_i: np.ndarray
    body_j: np.ndarray
    force: np.ndarray
    fn: np.ndarray
    branch: np.ndarray
    segments: np.ndarray


@dataclass(frozen=True)
class Walls:
    """The four walls in the order of ``WALL_IDS``: ``position`` (4,) their coordinate,
    ``length`` (4,) their current length, ``force`` (4,) the normal force of the particles on them.
    """

    position: np.ndarray
    length: np.ndarray
    force: np.ndarray


@dataclass(frozen=True)
class Frame:
    """Everything post reads about one frame."""

    record: FrameRecord
    bodies: Bodies
    contacts: FrameContacts
    walls: Walls


def read_frames_table(out_dir: str | Path) -> list[FrameRecord]:
    """Read and validate ``OUT_DIR/frames.csv``; one record per row, in file order."""
    path = Path(out_dir) / "frames.csv"
    if not files.is_file(path, OutputError):
        raise OutputError(path, "<file>", "an existing CSV file with one row per frame")
    rows = read_frame_rows(path, OutputError)  # checked complete (compute.output)
    if not rows:
        raise OutputError(path, "<rows>", "at least one frame row")
    missing = [c for c in FRAME_COLUMNS if c not in rows[0]]
    if missing:
        raise OutputError(path, missing[0], f"a column (header must hold {', '.join(FRAME_COLUMNS)})", list(rows[0]))
    records = [_frame_record(path, line, row) for line, row in enumerate(rows, start=2)]
    frames = [r.frame for r in records]
    if len(set(frames)) != len(frames):
        raise OutputError(path, "frame", "unique frame numbers", frames)
    return records


def _frame_record(path: Path, line: int, row: dict[str, str]) -> FrameRecord:
    def number(name: str, kind: type):
        text = (row[name] or "").strip()
        try:
            value = kind(text)
        except ValueError:
            raise OutputError(path, name, f"{kind.__name__} on line {line}", text) from None
        if kind is float and not np.isfinite(value):
            raise OutputError(path, name, f"a finite number on line {line}", text)
        return value

    equilibrated = (row["equilibrated"] or "").strip().lower()
    if equilibrated not in _BOOLEANS:
        raise OutputError(path, "equilibrated", f"1/0/true/false on line {line}", row["equilibrated"])
    return FrameRecord(frame=number("frame", int), time=number("time", float), step=number("step", int),
                       stage=number("stage", int), pressure_applied=number("pressure_applied", float),
                       equilibrated=_BOOLEANS[equilibrated],
                       box=tuple(number(name, float) for name in ("xmin", "xmax", "ymin", "ymax")))


def _read_vtu(path: Path, allow_empty: bool = False):
    return read_vtu(path, OutputError, allow_empty)


def _cell_field(mesh, path: Path, name: str, components: int = 1) -> np.ndarray:
    return cell_field(mesh, path, name, OutputError, components)


def _integer_field(mesh, path: Path, name: str) -> np.ndarray:
    return cell_field(mesh, path, name, OutputError, integer=True)


def read_bodies(path: str | Path) -> Bodies:
    """Read and validate a ``bodies_NNNNN.vtu`` frame (the bodies layout, plus the cell pressure)."""
    path = Path(path)
    lay = read_layout(path, OutputError)
    pressure = _cell_field(lay.mesh, path, "pressure")
    rigid_centres = np.concatenate([lay.points[c.data[:, 0]] for c in lay.mesh.cells if c.type == "vertex"]
                                   or [np.empty((0, 2))])
    meshes = tuple(MeshBlock(element=CELL_ELEMENT[c.type], cells=np.asarray(c.data, dtype=np.int64),
                             body=lay.body[lay.block == k], pressure=pressure[lay.block == k])
                   for k, c in enumerate(lay.mesh.cells) if c.type in CELL_ELEMENT)
    return Bodies(points=lay.points, radius=lay.radius, rigid=lay.rigid, rigid_ids=lay.body[lay.vertex_cells()],
                  rigid_centres=rigid_centres, meshes=meshes)


def read_contacts(path: str | Path, n_bodies: int) -> FrameContacts:
    """Read and validate a ``contacts_NNNNN.vtu`` frame of a packing of ``n_bodies`` bodies."""
    path = Path(path)
    mesh = _read_vtu(path, allow_empty=True)
    if mesh is None:
        return FrameContacts(body_i=np.empty(0, np.int64), body_j=np.empty(0, np.int64), force=np.empty((0, 2)),
                        fn=np.empty(0), branch=np.empty((0, 2)), segments=np.empty((0, 2, 2)))
    if any(c.type != "line" for c in mesh.cells):
        raise OutputError(path, "cells", "line cells only", sorted({c.type for c in mesh.cells}))
    body_i = _integer_field(mesh, path, "body_i")
    body_j = _integer_field(mesh, path, "body_j")
    if len(body_i) and (body_i.min() < 0 or body_i.max() >= n_bodies):
        raise OutputError(path, "cell_data.body_i", f"body ids in 0 .. {n_bodies - 1}")
    if len(body_j) and (body_j.min() < min(WALL_IDS) or body_j.max() >= n_bodies or np.any(body_j == body_i)):
        raise OutputError(path, "cell_data.body_j", f"body ids in 0 .. {n_bodies - 1} other than body_i, "
                                                    f"or wall ids -1 .. -4")
    points = np.asarray(mesh.points, dtype=float)[:, :2]
    lines = np.concatenate([c.data for c in mesh.cells])
    return FrameContacts(body_i=body_i, body_j=body_j, force=_cell_field(mesh, path, "force", 2),
                    fn=_cell_field(mesh, path, "fn"), branch=_cell_field(mesh, path, "branch", 2),
                    segments=points[lines])


def read_walls(path: str | Path) -> Walls:
    """Read and validate a ``walls_NNNNN.vtu`` frame; the walls are returned in WALL_IDS order."""
    path = Path(path)
    mesh = _read_vtu(path, allow_empty=True)
    if mesh is None or any(c.type != "line" for c in mesh.cells):
        raise OutputError(path, "cells", "four line cells (the box edges)")
    wall = _integer_field(mesh, path, "wall")
    if sorted(wall.tolist()) != sorted(WALL_IDS):
        raise OutputError(path, "cell_data.wall", "the four wall ids -1, -2, -3, -4 once each", wall.tolist())
    order = np.argsort(-wall)
    length = _cell_field(mesh, path, "length")[order]
    if length.min() <= 0:
        raise OutputError(path, "cell_data.length", "positive wall lengths", length.tolist())
    return Walls(position=_cell_field(mesh, path, "position")[order], length=length,
                 force=_cell_field(mesh, path, "force")[order])


def read_frame(out_dir: str | Path, record: FrameRecord) -> Frame:
    """Read the three VTU files of the frame described by ``record``."""
    bodies = read_bodies(frame_path(out_dir, "bodies", record.frame))
    return Frame(record=record, bodies=bodies,
                 contacts=read_contacts(frame_path(out_dir, "contacts", record.frame), bodies.n_bodies),
                 walls=read_walls(frame_path(out_dir, "walls", record.frame)))


def iter_frames(out_dir: str | Path) -> Iterator[Frame]:
    """Read the frames of ``out_dir`` one at a time, in the order of ``frames.csv``."""
    for record in read_frames_table(out_dir):
        yield read_frame(out_dir, record)
