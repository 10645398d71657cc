"""The table of measures of an output folder: one row per frame (``OUT_DIR/post/measures.csv``).

Columns (definitions in :mod:`post.measures`):

- ``frame, time, step, stage, pressure_applied, equilibrated``: copied from frames.csv;
- ``volume`` box area V; ``phi`` packing fraction; ``phi_contact`` the packing fraction of the
  contact boundaries (the same for T3); ``rigid_overlap`` the area rigid disks share with the
  deformable bodies' boundary polygons over V; ``phi_net`` = phi_contact - rigid_overlap, the
  fraction of the box the particles cover (NaN, these three, in a table written before they
  were measured);
- ``P, q, sigma_xx, sigma_yy, sigma_xy``: granular stress from the contacts (symmetric part);
- ``P_walls`` mean wall force / length; ``P_rel_diff`` = P / P_walls - 1, the equilibrium check
  (contacts against walls; ~0 on equilibrated frames);
- ``Z, Z_no_rattlers, Z_bulk, Z_constraints`` coordination numbers;
- ``n_contacts`` active contacts (pairs of bodies, walls included), ``n_wall_contacts`` those with
  a wall, ``n_rattlers``, ``n_particles``;
- ``K`` = phi dP/dphi by centred differences over the equilibrated frames; NaN on the other
  frames, and on all when fewer than two frames are equilibrated or phi does not increase
  strictly from one equilibrated frame to the next.
"""

from __future__ import annotations

import csv
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from post import measures
from post.frames import Frame, frame_path, read_frame, read_frames_table

COLUMNS = ("frame", "time", "step", "stage", "pressure_applied", "equilibrated", "volume", "phi", "phi_contact",
           "rigid_overlap", "phi_net", "P", "P_walls", "P_rel_diff", "q", "sigma_xx", "sigma_yy", "sigma_xy", "Z", "Z_no_rattlers", "Z_bulk", "Z_constraints", "n_contacts",
           "n_wall_contacts", "n_rattlers", "n_particles", "K")

Row = dict[str, float | int | bool]
_INTEGER_COLUMNS = ("frame", "step", "stage", "n_contacts", "n_wall_contacts", "n_rattlers", "n_particles")


def measure_frame(frame: Frame, min_contacts: int = 2, threshold: float = 1e-9) -> Row:
    """The measures of one frame (every column but K).

    min_contacts: rattler threshold (see measures.default_min_contacts); threshold: active
    contacts have fn > threshold x mean positive fn.
    """
    bodies, contacts, walls, record = frame.bodies, frame.contacts, frame.walls, frame.record
    volume = measures.box_area(walls.position)
    meshes = [(m.cells, m.body) for m in bodies.meshes]
    areas = measures.particle_areas(bodies.radius, bodies.rigid, bodies.points, meshes)
    contact_areas = measures.particle_areas(bodies.radius, bodies.rigid, bodies.points, meshes, straight=True)
    overlap = measures.rigid_deformable_overlap(bodies.points, meshes, bodies.rigid_centres,
                                                bodies.radius[bodies.rigid_ids]) / volume
    active = measures.active_contacts(contacts.fn, threshold)
    pairs = measures.contact_pairs(contacts.body_i[active], contacts.body_j[active])
    rattler = measures.rattlers(pairs, bodies.n_bodies, min_contacts)
    everyone = np.ones(bodies.n_bodies, dtype=bool)
    sigma = measures.granular_stress(contacts.force, contacts.branch, volume)
    P, q, _, _ = measures.stress_invariants(sigma)
    P_walls = measures.wall_pressure(walls.force, walls.length)
    return {
        "frame": record.frame, "time": record.time, "step": record.step, "stage": record.stage,
        "pressure_applied": record.pressure_applied, "equilibrated": record.equilibrated,
        "volume": volume, "phi": measures.packing_fraction(areas, volume),
        "phi_contact": measures.packing_fraction(contact_areas, volume), "rigid_overlap": overlap,
        "phi_net": measures.packing_fraction(contact_areas, volume) - overlap,
        "P": float(P), "P_walls": P_walls, "P_rel_diff": float(P / P_walls - 1) if P_walls else np.nan,
        "q": float(q), "sigma_xx": float(sigma[0, 0]), "sigma_yy": float(sigma[1, 1]),
        "sigma_xy": float(0.5 * (sigma[0, 1] + sigma[1, 0])),
        "Z": measures.coordination(pairs, everyone),
        "Z_no_rattlers": measures.coordination(pairs, ~rattler),
        "Z_bulk": measures.coordination(pairs, everyone, walls=False),
        "Z_constraints": measures.constraint_coordination(pairs, ~rattler),
        "n_contacts": len(pairs), "n_wall_contacts": int(np.sum(pairs[:, 0] < 0)),
        "n_rattlers": int(rattler.sum()), "n_particles": bodies.n_bodies,
    }


def measure_output(out_dir: str | Path, min_contacts: int = 2, threshold: float = 1e-9,
                   kept: str | Path | None = None) -> list[Row]:
    """The table of measures of an output folder, one row (dict keyed by COLUMNS) per frame of
    frames.csv, in its order. Reads the frames one at a time.

    ``kept``: an earlier table of the same folder (its measures.csv, made with the same
    ``min_contacts`` and ``threshold``). A frame whose VTU files are gone is taken from it, if it
    holds that frame at the same step and time; otherwise the missing file is an error. Why: the
    small files of a long run (its tables, its checkpoint) are carried from machine to machine to
    be resumed, and its frames, hundreds of megabytes, are not."""
    earlier = _rows_by_frame(kept) if kept is not None and Path(kept).is_file() else {}
    rows = []
    for record in read_frames_table(out_dir):
        row = earlier.get(record.frame)
        if row is not None and (row["step"], row["time"]) == (record.step, record.time) and not all(
                frame_path(out_dir, kind, record.frame).is_file() for kind in ("bodies", "contacts", "walls")):
            rows.append(row)
        else:
            rows.append(measure_frame(read_frame(out_dir, record), min_contacts, threshold))
    equilibrated = [row for row in rows if row["equilibrated"]]
    phi = np.array([row["phi"] for row in equilibrated])
    try:
        K = measures.bulk_modulus(phi, np.array([row["P"] for row in equilibrated]))
    except ValueError:  # fewer than two stages, or phi not increasing: K undefined (documented)
        K = np.full(len(equilibrated), np.nan)
    for row in rows:
        row["K"] = np.nan
    for row, k in zip(equilibrated, K):
        row["K"] = float(k)
    return rows


def write_measures(rows: Sequence[Row], path: str | Path) -> Path:
    """Write rows as CSV with the header COLUMNS (booleans as 0/1, floats round-trip exact)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as stream:
        writer = csv.writer(stream)
        writer.writerow(COLUMNS)
        for row in rows:
            writer.writerow([_format(row[c]) for c in COLUMNS])
    return path


def _format(value: float | int | bool) -> str:
    if isinstance(value, (bool, np.bool_, int, np.integer)):
        return str(int(value))
    return repr(float(value))


def _rows_by_frame(path: str | Path) -> dict[int, Row]:
    """The rows of a measures.csv (write_measures) by frame number, typed as measure_frame's."""
    rows = {}
    with Path(path).open(newline="") as stream:
        for raw in csv.DictReader(stream):
            row: Row = {c: float(raw.get(c, "nan")) for c in COLUMNS}
            for c in _INTEGER_COLUMNS:
                row[c] = int(raw[c])
            row["equilibrated"] = bool(int(raw["equilibrated"]))
            rows[row["frame"]] = row
    return rows


def read_measures(path: str | Path) -> np.ndarray:
    """Read a measures.csv as a numpy structured array (one field per column, shape (n_frames,))."""
    return np.atleast_1d(np.genfromtxt(path, delimiter=",", names=True, dtype=None, encoding="utf-8"))
