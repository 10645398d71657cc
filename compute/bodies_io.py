"""The bodies file (``bodies.vtu``): reading with validation, and writing.

Layout (docs/FORMATS.md): a ``vertex`` cell per rigid disk at its centre, ``triangle`` /
``triangle6`` cells for deformable bodies, and cell_data ``body``, ``material``, ``radius``.
The same layout, with extra fields, is used for the bodies frames written by compute.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from compute import files
from compute.errors import InputError, SceneError
from compute.schema import SCALE, TINY
from compute.vtu_io import cell_field, read_vtu

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


@dataclass(frozen=True)
class Layout:
    """A bodies file (a scene's or a frame's) checked for the layout both share.

    ``points`` (n, 2) within ±SCALE; ``mesh.cells`` blocks of type vertex, triangle or triangle6
    whose indices point into the points; per cell, concatenated over the blocks: ``block`` (the
    block index), ``body`` (ids contiguous 0..N-1); per body: ``radius`` (N,) positive, one per
    body, and ``rigid`` (N,) (one vertex cell per rigid body, no triangle on it)."""

    mesh: object
    points: np.ndarray
    block: np.ndarray
    body: np.ndarray
    radius: np.ndarray
    rigid: np.ndarray

    @property
    def n_bodies(self) -> int:
        return len(self.radius)

    def vertex_cells(self) -> np.ndarray:
        """Mask (n_cells,) of the vertex (rigid disk) cells."""
        return np.isin(self.block, [k for k, c in enumerate(self.mesh.cells) if c.type == "vertex"])


def read_layout(path: str | Path, error: type[InputError] = SceneError) -> Layout:
    """Read ``path`` and check the bodies layout (:class:`Layout`); problems raise ``error``."""
    path = Path(path)
    mesh = read_vtu(path, error)
    points = np.asarray(mesh.points, dtype=float)
    if not np.all(np.isfinite(points)) or (points.size and np.abs(points).max() > SCALE):
        raise error(path, "points", f"finite coordinates within ±{SCALE:g}")
    if points.shape[1] > 2 and np.any(points[:, 2:] != 0.0):
        i = int(np.flatnonzero(np.any(points[:, 2:] != 0.0, axis=1))[0])
        raise error(path, "points", "points in the plane z = 0 (the toolkit is 2D)", f"z = {points[i, 2]!r} at point {i}")
    points = points[:, :2]
    for block in mesh.cells:
        if block.type not in ("vertex", *CELL_ELEMENT):
            raise error(path, "cells", "cell blocks of type vertex, triangle or triangle6", block.type)
        if block.data.size and (block.data.min() < 0 or block.data.max() >= len(points)):
            raise error(path, f"cells ({block.type})", f"point indices in 0..{len(points) - 1}",
                        int(block.data.max() if block.data.max() >= len(points) else block.data.min()))
    body = cell_field(mesh, path, "body", error, integer=True)
    radius = cell_field(mesh, path, "radius", error)
    n_bodies = int(body.max()) + 1 if len(body) else 0
    if n_bodies == 0 or body.min() < 0 or n_bodies > len(body) or len(np.unique(body)) != n_bodies:
        raise error(path, "cell_data.body", "contiguous body ids 0..N-1 and at least one body",
                    f"ids from {body.min() if len(body) else None} to {body.max() if len(body) else None}")
    if radius.min() < TINY or radius.max() > SCALE:
        raise error(path, "cell_data.radius", f"positive radii in [{TINY:g}, {SCALE:g}]",
                    float(radius.min() if radius.min() < TINY else radius.max()))
    per_body = np.full(n_bodies, np.nan)
    per_body[body] = radius
    if np.any(per_body[body] != radius):
        b = int(body[np.argmax(per_body[body] != radius)])
        raise error(path, f"cell_data of body {b}", "one radius per body")
    block = np.repeat(np.arange(len(mesh.cells)), [len(c.data) for c in mesh.cells])
    layout = Layout(mesh, points, block, body, per_body, np.zeros(n_bodies, bool))
    vertex = layout.vertex_cells()
    layout.rigid[body[vertex]] = True
    if len(np.unique(body[vertex])) != vertex.sum() or np.any(layout.rigid[body[~vertex]]):
        raise error(path, "cell_data.body", "one vertex cell per rigid body and no triangles on it")
    return layout


def read_bodies(path: Path, material_names: list[str], materials: dict) -> dict:
    """Read and validate the scene's bodies file ``path``; return the body arrays of
    :class:`compute.scene.Scene`."""
    path = Path(path)
    lay = read_layout(path, SceneError)
    mat = cell_field(lay.mesh, path, "material", SceneError, integer=True)
    if mat.min() < 0 or mat.max() >= len(material_names):
        raise SceneError(path, "cell_data.material", f"indices into bodies.materials (0..{len(material_names) - 1})",
                         int(mat.min() if mat.min() < 0 else mat.max()))
    body_material = np.full(lay.n_bodies, -1)
    body_material[lay.body] = mat
    if np.any(body_material[lay.body] != mat):
        b = int(lay.body[np.argmax(body_material[lay.body] != mat)])
        raise SceneError(path, f"cell_data of body {b}", "one material per body")
    vertex = lay.vertex_cells()
    kinds = {materials[material_names[m]].kind for m in mat[vertex]}
    if kinds - {"rigid"}:
        raise SceneError(path, "cell_data.material", "a rigid material for vertex (rigid disk) cells", sorted(kinds))
    deformable = []
    for k, block in enumerate(lay.mesh.cells):
        if block.type not in CELL_ELEMENT:
            continue
        body = lay.body[lay.block == k]
        for b in np.unique(body):
            m = materials[material_names[body_material[b]]]
            if m.kind == "rigid" or m.element != CELL_ELEMENT[block.type]:
                raise SceneError(path, f"cell_data.material of body {b}",
                                 f"one neo_hookean material with element {CELL_ELEMENT[block.type]}")
            cells = block.data[body == b]
            used, local = np.unique(cells, return_inverse=True)
            deformable.append(DeformableBody(int(b), lay.points[used].copy(), local.reshape(cells.shape).astype(np.int64),
                                             CELL_ELEMENT[block.type]))
    rigid_ids = lay.body[vertex]
    centres = np.concatenate([lay.points[c.data[:, 0]] for c in lay.mesh.cells if c.type == "vertex"]
                             or [np.zeros((0, 2))])
    deformable.sort(key=lambda d: d.body)
    out = dict(body_material=body_material, radius=lay.radius, rigid_ids=rigid_ids, rigid_centres=centres,
               rigid_radii=lay.radius[rigid_ids], deformable=deformable)
    _check_no_overlap(path, out)
    return out


def body_centres(bodies: dict) -> np.ndarray:
    """Centres (n_bodies, 2): rigid centres; for a deformable disk the centre of the circle
    through its outermost nodes (``circle_centre``)."""
    n = len(bodies["body_material"])
    c = np.zeros((n, 2))
    c[bodies["rigid_ids"]] = bodies["rigid_centres"]
    for d in bodies["deformable"]:
        c[d.body] = circle_centre(d.points)
    return c


def circle_centre(points: np.ndarray, ring: float = 0.05) -> np.ndarray:
    """Centre (2,) of a meshed disk whose boundary nodes lie on its circle: the least-squares
    circle (|x - c|² = ρ², linear in c and ρ² - |c|²) through the nodes within ``ring`` × the
    largest distance of the farthest one from the nodes' mean. Exact for nodes on a circle, where
    the middle of the bounding box is not: a mesh whose boundary has an odd number of nodes, or
    uneven ones, is not symmetric about it (a 181-triangle disk's box middle is off by 2.9e-3 of
    its radius, which the overlap check of a jammed packing reads as an overlap)."""
    mean = points.mean(axis=0)
    dist = np.linalg.norm(points - mean, axis=1)
    outer = points[dist >= (1.0 - ring) * dist.max()]
    if len(outer) < 3:
        return mean
    a = np.column_stack([2.0 * outer, np.ones(len(outer))])
    solution, *_ = np.linalg.lstsq(a, np.sum(outer**2, axis=1), rcond=None)
    return solution[:2]


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


# zlib: a large scene's files several times smaller for little write time
# (benchmarks/results/design_figures.md); meshio, VTK and ParaView read it as they read raw binary
VTU_COMPRESSION = "zlib"


def write_bodies(path: Path, centres: np.ndarray, radii: np.ndarray, material: np.ndarray,
                 meshes: dict | None = None, point_data: dict | None = None,
                 cell_data: dict | None = None) -> None:
    """Write bodies in the FORMATS.md layout (atomically, compute.files).

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
    mesh = meshio.Mesh(np.concatenate(pts), blocks, point_data=pdat, cell_data=cdat)
    files.write_atomic(path, lambda tmp: meshio.write(tmp, mesh, file_format="vtu", binary=True,
                                                      compression=VTU_COMPRESSION))
