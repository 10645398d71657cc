"""Synthetic output folders following docs/FORMATS.md, written with meshio, for the post tests.

:func:`write_square_lattice`: n x n disks of diameter d on a square lattice of spacing s filling
the box [0, n s]^2, the walls at pressure P. Every contact (disk-disk and disk-wall) carries
fn = P s, so that sigma = P I, P = P_walls = P_applied, Z = 4 (walls counting) and, for touching
rigid disks (s = d), phi = pi/4. Options: some disks deformable (fan meshes, T3 or T6 with
mid-side nodes on the circle), whose contacts are written as two candidates carrying fn/2 each,
as node-to-segment contacts would be; one small rattler in a hole of the lattice, touching
nothing, with a zero-force candidate. Checkpoints are not written (post does not read them)."""

from __future__ import annotations

from pathlib import Path

import meshio
import numpy as np

FRAME_HEADER = "frame,time,step,stage,pressure_applied,equilibrated,xmin,xmax,ymin,ymax"
HISTORY_HEADER = ("time,step,stage,pressure_applied,xmin,xmax,ymin,ymax,phi,nlgs_sweeps,nlgs_residual,"
                  "kinetic_energy,inertial_number,n_contacts")
RATTLER_RADIUS = 0.1  # in units of d; the holes of the square lattice have radius (sqrt(2) - 1) d / 2


def disk_fan(centre: np.ndarray, radius: float, sectors: int, element: str) -> tuple[np.ndarray, np.ndarray]:
    """A disk meshed by hand as a fan of ``sectors`` triangles around its centre, counter-clockwise.

    Returns points (n_points, 2) and cells (sectors, 3) for "T3", (sectors, 6) in VTK order for
    "T6" (mid-side nodes on the spokes at mid-length, on the circle for the rim edges).
    """
    k = np.arange(sectors)
    angle = 2 * np.pi * k / sectors
    rim = centre + radius * np.stack([np.cos(angle), np.sin(angle)], axis=1)
    nxt = (k + 1) % sectors
    if element == "T3":
        return np.vstack([centre, rim]), np.stack([np.zeros_like(k), 1 + k, 1 + nxt], axis=1)
    spoke_mid = 0.5 * (centre + rim)
    arc_angle = angle + np.pi / sectors
    arc_mid = centre + radius * np.stack([np.cos(arc_angle), np.sin(arc_angle)], axis=1)
    points = np.vstack([centre, rim, spoke_mid, arc_mid])
    spoke0, arc0 = 1 + sectors, 1 + 2 * sectors
    cells = np.stack([np.zeros_like(k), 1 + k, 1 + nxt, spoke0 + k, arc0 + k, spoke0 + nxt], axis=1)
    return points, cells


def fan_area(radius: float, sectors: int, element: str) -> float:
    """Exact area of :func:`disk_fan`: the polygon, plus for T6 the parabolic segment on each rim
    chord, 4/3 of the triangle (chord, sagitta) by Archimedes' quadrature of the parabola."""
    theta = 2 * np.pi / sectors
    polygon = sectors * 0.5 * radius**2 * np.sin(theta)
    if element == "T3":
        return polygon
    chord, sagitta = 2 * radius * np.sin(theta / 2), radius * (1 - np.cos(theta / 2))
    return polygon + sectors * 4 / 3 * 0.5 * chord * sagitta


def _vec3(v: np.ndarray) -> np.ndarray:
    return np.column_stack([v, np.zeros(len(v))])


def _lattice(n: int, s: float, rattler: bool):
    """Centres (N, 2) of the lattice of spacing s (and of the rattler, id n^2, in the hole at (s, s)),
    and its contact candidates for P = 1: body_i, body_j (M,), normal, start, end (M, 2), fn (M,).
    Each contact carries the force on a strip of width s, fn = P s; a wall is at s/2 from a centre."""
    ids = np.arange(n * n).reshape(n, n)          # ids[row, col], centre ((col + 1/2) s, (row + 1/2) s)
    centre = s * (np.stack(np.meshgrid(np.arange(n), np.arange(n)), axis=-1).reshape(-1, 2) + 0.5)
    pieces = [  # (body_i, body_j, normal)
        (ids[:, :-1].ravel(), ids[:, 1:].ravel(), (1.0, 0.0)),
        (ids[:-1, :].ravel(), ids[1:, :].ravel(), (0.0, 1.0)),
        (ids[:, 0], np.full(n, -1), (-1.0, 0.0)), (ids[:, -1], np.full(n, -2), (1.0, 0.0)),
        (ids[0, :], np.full(n, -3), (0.0, -1.0)), (ids[-1, :], np.full(n, -4), (0.0, 1.0)),
    ]
    body_i = np.concatenate([p[0] for p in pieces])
    body_j = np.concatenate([p[1] for p in pieces])
    normal = np.concatenate([np.tile(p[2], (len(p[0]), 1)) for p in pieces])
    start = centre[body_i]
    end = np.where((body_j >= 0)[:, None], centre[np.maximum(body_j, 0)], start + 0.5 * s * normal)
    fn = np.full(len(body_i), s)
    if rattler:  # a zero-force candidate between the rattler and disk 0
        centre = np.vstack([centre, [s, s]])
        body_i, body_j = np.append(body_i, n * n), np.append(body_j, 0)
        normal = np.vstack([normal, (centre[0] - centre[-1]) / np.linalg.norm(centre[0] - centre[-1])])
        start, end = np.vstack([start, centre[-1]]), np.vstack([end, centre[0]])
        fn = np.append(fn, 0.0)
    return centre, body_i, body_j, normal, start, end, fn


def _bodies_mesh(centre: np.ndarray, soft: np.ndarray, radius: np.ndarray, element: str, sectors: int,
                 P: float) -> meshio.Mesh:
    """Rigid disks as vertex cells, the soft ones as fan meshes with cell pressure P."""
    rigid_ids, soft_ids = np.flatnonzero(~soft), np.flatnonzero(soft)
    fans = [disk_fan(centre[b], radius[b], sectors, element) for b in soft_ids]
    points = np.vstack([centre[rigid_ids], *(p for p, _ in fans)])
    offsets = len(rigid_ids) + np.cumsum([0] + [len(p) for p, _ in fans[:-1]])
    cells, body, kind = [], [], []
    if len(rigid_ids):
        cells.append(("vertex", np.arange(len(rigid_ids))[:, None]))
        body.append(rigid_ids)
        kind.append(np.zeros(len(rigid_ids), int))
    if fans:
        cells.append(({"T3": "triangle", "T6": "triangle6"}[element],
                      np.vstack([c + o for (_, c), o in zip(fans, offsets)])))
        body.append(np.repeat(soft_ids, sectors))
        kind.append(np.ones(len(body[-1]), int))
    zeros = [np.zeros(len(b)) for b in body]
    return meshio.Mesh(
        _vec3(points), cells,
        point_data={"displacement": np.zeros((len(points), 3)), "velocity": np.zeros((len(points), 3))},
        cell_data={"body": body, "material": kind, "radius": [radius[b] for b in body], "rotation": zeros,
                   "angular_velocity": zeros, "cauchy_stress": [np.zeros((len(b), 9)) for b in body],
                   "pressure": [k * P for k in kind], "von_mises": zeros})


def write_square_lattice(out_dir: str | Path, n: int = 4, d: float = 1.0, pressures=(0.01, 0.1),
                         spacings=None, equilibrated=None, deformable=(), element: str = "T6",
                         sectors: int = 16, rattler: bool = False) -> Path:
    """Write an output folder with a frame of the lattice per pressure; return out_dir.

    spacings: lattice spacing of each frame in units of d (default 1: touching disks; < 1 mimics
    the overlaps of a compressed packing, so that phi = pi/4 / spacing^2 grows);
    equilibrated: flag of each frame (default all True);
    deformable: ids of the disks meshed as fans (body ids are row * n + col, the rattler is n^2).
    """
    out = Path(out_dir)
    (out / "frames").mkdir(parents=True, exist_ok=True)
    spacings = np.ones(len(pressures)) if spacings is None else spacings
    equilibrated = [True] * len(pressures) if equilibrated is None else equilibrated
    soft = np.isin(np.arange(n * n + rattler), list(deformable))  # the rattler is rigid
    radius = np.where(np.arange(n * n + rattler) < n * n, d / 2, RATTLER_RADIUS * d)
    lines, history = [FRAME_HEADER], []
    for frame, (P, spacing, done) in enumerate(zip(pressures, spacings, equilibrated)):
        s, time, P = float(spacing) * d, 0.5 * frame, float(P)
        L = n * s
        centre, body_i, body_j, normal, start, end, unit_fn = _lattice(n, s, rattler)
        lines.append(f"{frame},{time!r},{100 * frame},{frame},{P!r},{int(done)},0.0,{L!r},0.0,{L!r}")
        meshio.write(out / "frames" / f"bodies_{frame:05d}.vtu",
                     _bodies_mesh(centre, soft, radius, element, sectors, P))

        # A deformable body's contacts are written as two candidates carrying half the force each.
        split = soft[body_i] | (soft[np.maximum(body_j, 0)] & (body_j >= 0))
        rows = np.concatenate([np.arange(len(body_i)), np.flatnonzero(split)])
        fn = P * unit_fn[rows] * np.where(split, 0.5, 1.0)[rows]
        contact_point = np.where((body_j[rows] >= 0)[:, None], 0.5 * (start[rows] + end[rows]), end[rows])
        meshio.write(out / "frames" / f"contacts_{frame:05d}.vtu", meshio.Mesh(
            _vec3(np.stack([start[rows], end[rows]], axis=1).reshape(-1, 2)),
            [("line", np.arange(2 * len(rows)).reshape(-1, 2))],
            cell_data={"body_i": [body_i[rows]], "body_j": [body_j[rows]], "normal": [_vec3(normal[rows])],
                       "force": [_vec3(fn[:, None] * normal[rows])], "fn": [fn], "ft": [np.zeros(len(rows))],
                       "gap": [np.zeros(len(rows))], "branch": [_vec3(end[rows] - start[rows])],
                       "contact_point": [_vec3(contact_point)]}))

        meshio.write(out / "frames" / f"walls_{frame:05d}.vtu", meshio.Mesh(
            _vec3(np.array([[0.0, 0.0], [L, 0.0], [L, L], [0.0, L]])),
            [("line", np.array([[0, 3], [1, 2], [0, 1], [3, 2]]))],
            cell_data={"wall": [np.array([-1, -2, -3, -4])], "position": [np.array([0.0, L, 0.0, L])],
                       "length": [np.full(4, L)], "force": [np.full(4, P * L)],
                       "pressure_applied": [np.full(4, P)], "velocity": [np.zeros(4)]}))
        phi = (np.pi * np.sum(radius[~soft] ** 2) + soft.sum() * fan_area(d / 2, sectors, element)) / L**2
        history.append(f"{time},{100 * frame},{frame},{P},0.0,{L},0.0,{L},{phi},1,0.0,0.0,0.0,{len(rows)}")
    (out / "frames.csv").write_text("\n".join(lines) + "\n")
    (out / "history.csv").write_text("\n".join([HISTORY_HEADER, *history]) + "\n")
    _write_collections(out, len(pressures))
    return out


def _write_collections(out: Path, n_frames: int) -> None:
    for kind in ("bodies", "contacts", "walls"):
        datasets = "\n".join(f'    <DataSet timestep="{k * 0.5}" file="frames/{kind}_{k:05d}.vtu"/>'
                             for k in range(n_frames))
        (out / f"{kind}.pvd").write_text('<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1">\n'
                                         f"  <Collection>\n{datasets}\n  </Collection>\n</VTKFile>\n")
