"""The bodies file (``bodies.vtu``): reading with validation, and writing.

Layout (docs/FORMATS.md): a ``vertex`` cell per rigid disk at its centre, ``triangle`` /
``triangle6`` cells for deformable bodies, and cell_data ``body``, ``material``, ``radius``.
The same layout, with extra fields, is used for the bodies frames written by compute.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from compute.errors import SceneError
from compute.schema import SCALE, TINY

CELL_ELEMENT = {"triangle": "T3", "triangle6": "T6"}
ELEMENT_CELL = {v: k for k, v in CELL_ELEMENT.items()}
OVERLAP_TOLERANCE = 1e-3  # relative to the smaller radius: a jammed NSCD state carries
# interpenetrations at the solver tolerance (well below this); anything larger is an error


@dataclass(frozen=True)
class DeformableBody:
    """Mesh of one deformable body: reference nodes (n, 2) and cells (ne, 3|6)."""

    body: int
    points: np.ndarray
    cells: np.ndarray
    element: str


def read_bodies(path: Path, material_names: list[str], materials: dict) -> dict:
    """Read and validate ``path``; return the body arrays of :class:`compute.scene.Scene`."""
    from meshio import vtu  # not meshio.read, which prints and calls sys.exit on a corrupt file

    path = Path(path)
    if not path.is_file():
        raise SceneError(path, "<file>", "an existing VTU bodies file")
    try:
        mesh = vtu.read(path)
    except Exception as exc:  # meshio raises many types on truncated / corrupt XML
        raise SceneError(path, "<file>", "a complete, readable VTU file", f"{type(exc).__name__}: {exc}") from None
    points = np.asarray(mesh.points, dtype=float)[:, :2]
    if not np.all(np.isfinite(points)) or (points.size and np.abs(points).max() > SCALE):
        raise SceneError(path, "points", f"finite coordinates within ±{SCALE:g}")
    for block in mesh.cells:
        if block.data.size and (block.data.min() < 0 or block.data.max() >= len(points)):
            raise SceneError(path, f"cells ({block.type})", f"point indices in 0..{len(points) - 1}",
                             int(block.data.max() if block.data.max() >= len(points) else block.data.min()))
    fields = {}
    for name in ("body", "material", "radius"):
        if name not in mesh.cell_data:
            raise SceneError(path, f"cell_data.{name}", "a cell array on every cell block (missing)")
        blocks = mesh.cell_data[name]
        if len(blocks) != len(mesh.cells) or any(len(b) != len(c.data) for b, c in zip(blocks, mesh.cells)):
            raise SceneError(path, f"cell_data.{name}", "one value per cell")
        fields[name] = [np.asarray(b).reshape(len(b), -1)[:, 0] for b in blocks]
        if name != "radius" and any(not np.all(np.isfinite(b) & (b == np.round(b)) & (np.abs(b) < 2**31))
                                    for b in fields[name]):
            raise SceneError(path, f"cell_data.{name}", "integers (below 2^31 in magnitude)")
    n_cells = sum(len(c.data) for c in mesh.cells)
    if any(len(b) and (b.max() >= n_cells) for b in fields["body"]):
        raise SceneError(path, "cell_data.body", f"contiguous body ids 0..N-1 (N <= {n_cells} cells)",
                         int(max(b.max() for b in fields["body"] if len(b))))

    rigid_ids, rigid_centres, rigid_radii, deformable = [], [], [], []
    n_bodies = 1 + max((int(b.max()) for b in fields["body"] if len(b)), default=-1)
    body_material = np.full(n_bodies, -1)
    radius = np.full(n_bodies, np.nan)
    for k, block in enumerate(mesh.cells):
        body = fields["body"][k].astype(np.int64)
        mat = fields["material"][k].astype(np.int64)
        rad = fields["radius"][k].astype(float)
        if len(body) and body.min() < 0:
            raise SceneError(path, "cell_data.body", "body ids >= 0", int(body.min()))
        if len(mat) and (mat.min() < 0 or mat.max() >= len(material_names)):
            raise SceneError(path, "cell_data.material", f"indices into bodies.materials (0..{len(material_names) - 1})",
                             int(mat.min() if mat.min() < 0 else mat.max()))
        if not np.all(np.isfinite(rad)) or (len(rad) and (rad.min() < TINY or rad.max() > SCALE)):
            raise SceneError(path, "cell_data.radius", f"positive radii in [{TINY:g}, {SCALE:g}]",
                             float(rad.min() if len(rad) and rad.min() < TINY else rad.max()))
        if block.type == "vertex":
            kinds = {materials[material_names[m]].kind for m in mat}
            if kinds - {"rigid"}:
                raise SceneError(path, "cell_data.material", "a rigid material for vertex (rigid disk) cells",
                                 sorted(kinds))
            rigid_ids.append(body)
            rigid_centres.append(points[block.data[:, 0]])
            rigid_radii.append(rad)
        elif block.type in CELL_ELEMENT:
            for b in np.unique(body):
                sel = body == b
                m = materials[material_names[int(mat[sel][0])]]
                if np.any(mat[sel] != mat[sel][0]) or m.kind == "rigid" or m.element != CELL_ELEMENT[block.type]:
                    raise SceneError(path, f"cell_data.material of body {b}",
                                     f"one neo_hookean material with element {CELL_ELEMENT[block.type]}")
                cells = block.data[sel]
                used, local = np.unique(cells, return_inverse=True)
                deformable.append(DeformableBody(int(b), points[used].copy(),
                                                 local.reshape(cells.shape).astype(np.int64),
                                                 CELL_ELEMENT[block.type]))
        else:
            raise SceneError(path, "cells", "cell blocks of type vertex, triangle or triangle6", block.type)
        for b, m, r in zip(body, mat, rad):
            if body_material[b] not in (-1, m) or not (np.isnan(radius[b]) or radius[b] == r):
                raise SceneError(path, f"cell_data of body {b}", "one material and one radius per body")
        body_material[body] = mat
        radius[body] = rad
    if n_bodies == 0:
        raise SceneError(path, "cells", "at least one body")
    if np.any(body_material < 0):
        raise SceneError(path, "cell_data.body", f"contiguous body ids 0..{n_bodies - 1}",
                         f"missing {np.flatnonzero(body_material < 0)[:5].tolist()}")
    rigid_ids = np.concatenate(rigid_ids) if rigid_ids else np.zeros(0, np.int64)
    if len(np.unique(rigid_ids)) != len(rigid_ids):
        raise SceneError(path, "cell_data.body", "one vertex cell per rigid body")
    deformable.sort(key=lambda d: d.body)
    out = dict(
        body_material=body_material, radius=radius, rigid_ids=rigid_ids,
        rigid_centres=np.concatenate(rigid_centres) if rigid_centres else np.zeros((0, 2)),
        rigid_radii=np.concatenate(rigid_radii) if rigid_radii else np.zeros(0),
        deformable=deformable,
    )
    _check_no_overlap(path, out)
    return out


def body_centres(bodies: dict) -> np.ndarray:
    """Centres (n_bodies, 2): rigid centres, deformable centroids of the nodes' bounding circle."""
    n = len(bodies["body_material"])
    c = np.zeros((n, 2))
    c[bodies["rigid_ids"]] = bodies["rigid_centres"]
    for d in bodies["deformable"]:
        c[d.body] = 0.5 * (d.points.min(axis=0) + d.points.max(axis=0))
    return c


def _check_no_overlap(path: Path, bodies: dict) -> None:
    """Stop on any pair of bodies whose nominal disks overlap by more than OVERLAP_TOLERANCE."""
    from scipy.spatial import cKDTree

    c, r = body_centres(bodies), bodies["radius"]
    if len(r) < 2:
        return
    pairs = cKDTree(c).query_pairs(2.0 * r.max(), output_type="ndarray")
    if len(pairs) == 0:
        return
    i, j = pairs[:, 0], pairs[:, 1]
    overlap = (r[i] + r[j]) - np.linalg.norm(c[i] - c[j], axis=1)
    bad = overlap > OVERLAP_TOLERANCE * np.minimum(r[i], r[j])
    if bad.any():
        k = int(np.argmax(np.where(bad, overlap, -np.inf)))
        raise SceneError(path, "points/radius",
                         "non-overlapping bodies", f"bodies {int(i[k])} and {int(j[k])} overlap by {overlap[k]:.3g}")


def write_bodies(path: Path, centres: np.ndarray, radii: np.ndarray, material: np.ndarray,
                 meshes: dict | None = None, point_data: dict | None = None,
                 cell_data: dict | None = None) -> None:
    """Write bodies in the FORMATS.md layout.

    centres (n, 2), radii (n,), material (n,) for every body; ``meshes`` maps a deformable body
    id to ``(points (m, 2), cells (ne, 3|6), element)`` in the current configuration (those
    bodies get triangle cells instead of a vertex). ``point_data`` / ``cell_data`` map a field
    name to ``{"rigid": array over the rigid bodies in increasing id order, "deformable": {body
    id: array over that body's nodes / cells}}``.
    """
    import meshio

    meshes = meshes or {}
    point_data, cell_data = point_data or {}, cell_data or {}
    n = len(radii)
    rigid = np.array([b for b in range(n) if b not in meshes], dtype=np.int64)
    pts = [np.column_stack([centres[rigid], np.zeros(len(rigid))])]
    pdat = {k: [np.asarray(v["rigid"], float)] for k, v in point_data.items()}
    blocks, cdat = [], {k: [] for k in ("body", "material", "radius", *cell_data)}
    if len(rigid):
        blocks.append(("vertex", np.arange(len(rigid)).reshape(-1, 1)))
        for k, v in (("body", rigid), ("material", material[rigid]), ("radius", radii[rigid])):
            cdat[k].append(v)
        for k, v in cell_data.items():
            cdat[k].append(np.asarray(v["rigid"], float))
    offset = len(rigid)
    by_type: dict[str, list] = {}
    for b in sorted(meshes):
        p, cells, element = meshes[b]
        pts.append(np.column_stack([p, np.zeros(len(p))]))
        for k, v in point_data.items():
            pdat[k].append(np.asarray(v["deformable"][b], float))
        by_type.setdefault(ELEMENT_CELL[element], []).append((b, cells + offset))
        offset += len(p)
    for ctype, items in by_type.items():
        blocks.append((ctype, np.concatenate([c for _, c in items])))
        ids = np.concatenate([np.full(len(c), b) for b, c in items])
        cdat["body"].append(ids)
        cdat["material"].append(material[ids])
        cdat["radius"].append(radii[ids])
        for k, v in cell_data.items():
            cdat[k].append(np.concatenate([np.asarray(v["deformable"][b], float) for b, _ in items]))
    pdat = {k: np.concatenate(v) for k, v in pdat.items()}
    meshio.write(path, meshio.Mesh(np.concatenate(pts), blocks, point_data=pdat, cell_data=cdat),
                 file_format="vtu", binary=True, compression=None)
