"""Finite-element meshes of disks, made with gmsh.

A reference mesh (unit radius, centred at the origin) is made once per ``(element,
n_elements)`` and per process, then scaled and translated for every deformable body with
:meth:`DiskMesh.placed` (which never remeshes).

Public API
----------
- :class:`DiskMesh`: frozen record ``points (n_nodes, 2)``, ``cells (n_elements, 3 | 6)``,
  ``element "T3" | "T6"``; ``area``, ``element_areas``, ``boundary_nodes``, ``placed``,
  ``write`` / ``read`` (meshio, ``.msh`` or ``.vtu``), ``to_meshio``.
- :func:`reference_disk_mesh`: the cached unit-disk mesh with about ``n_elements`` triangles,
  or graded toward the circle (``boundary_segments``).
- :func:`disk_mesh_resolution`: the boundary segment count and mesh size chosen for a target.
- :func:`clear_mesh_cache`: forget every cached mesh (tests, memory).

Conventions: nodes used by at least one cell only, numbered from 0; triangles counter-clockwise
(positive area); ``triangle6`` node order as meshio / VTK: three vertices, then the midside
nodes of edges (0, 1), (1, 2), (2, 0). For ``T6`` the midside nodes of boundary edges lie on
the circle.

gmsh is not thread-safe and holds one global state per process: every gmsh session here runs
under a module-level lock, starts with ``gmsh.initialize(interruptible=False)`` (no signal
handler, so it works in dask worker threads) and is finalized at the end. If the caller already
has a gmsh session open, it is reused: a private model is added and removed, and the options
touched here are restored.
"""

from __future__ import annotations

import functools
import math
import operator
import os
import threading
from dataclasses import dataclass
from typing import Literal

import numpy as np

from compute.bodies_io import CELL_ELEMENT, ELEMENT_CELL
from compute.fem.elements import element_type
from compute.fem.topology import boundary_loop, signed_areas

__all__ = [
    "DiskMesh",
    "ELEMENTS",
    "reference_disk_mesh",
    "disk_mesh_resolution",
    "clear_mesh_cache",
]

ELEMENTS = ("T3", "T6")

_NODES_PER_CELL = {"T3": 3, "T6": 6}

# Mesh size h = _SIZE_PER_SEGMENT / n_segments for a unit radius (0.3 for 20 segments, the
# measured recipe for exactly 92 triangles). Element count measured with gmsh 4.15:
# N_e ~ 0.2 n^2 + 0.5 n (n = 20 -> 92, 60 -> 738, 140 -> 3992).
_SIZE_PER_SEGMENT = 6.0
_COUNT_A, _COUNT_B = 0.2, 0.5
# Mesh-size factors tried, in order of preference, when the default size misses the target by
# more than _GOOD_ENOUGH (only happens for coarse meshes, where counts move in jumps).
_SIZE_FACTORS = (1.0, 0.95, 1.05, 0.9, 1.1, 0.85, 0.8)
_GOOD_ENOUGH = 0.03

# Boundary-graded meshes: element size = boundary segment length + GRADING x distance to the
# circle, up to the interior size (0.3: about 4100 T6 elements for 480 segments and an interior
# of 1000 elements, against 5200 for 0.2, with the same boundary resolution).
GRADING = 0.3

_GMSH_LOCK = threading.Lock()

# gmsh options pinned for every meshing (and restored afterwards when the caller owns the
# gmsh session), so that results do not depend on the caller's settings.
_PINNED_OPTIONS = {
    "General.Terminal": 0.0,
    "Mesh.Algorithm": 6.0,  # Frontal-Delaunay (the gmsh default)
    "Mesh.MeshSizeMin": 0.0,
    "Mesh.MeshSizeFactor": 1.0,
    "Mesh.MeshSizeFromCurvature": 0.0,
    "Mesh.MeshSizeFromPoints": 1.0,
    "Mesh.MeshSizeExtendFromBoundary": 1.0,
    "Mesh.HighOrderOptimize": 0.0,
    "Mesh.SecondOrderLinear": 0.0,  # midside nodes on the geometry (the circle)
    "Mesh.RandomSeed": 1.0,
}


# --------------------------------------------------------------------------------------------
# The mesh record
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class DiskMesh:
    """A triangular mesh of a disk.

    Attributes
    ----------
    points : float64 array (n_nodes, 2)
        Node coordinates (read-only).
    cells : int64 array (n_elements, 3) for "T3", (n_elements, 6) for "T6"
        Node indices per triangle, counter-clockwise; for T6 the vertices then the midside
        nodes of edges (0, 1), (1, 2), (2, 0) (meshio ``triangle6`` order). Read-only.
    element : "T3" | "T6"
    """

    points: np.ndarray
    cells: np.ndarray
    element: Literal["T3", "T6"]

    def __post_init__(self) -> None:
        if self.element not in ELEMENTS:
            raise ValueError(f"DiskMesh: element must be one of {ELEMENTS}, got {self.element!r}")
        points = np.array(self.points, dtype=np.float64)
        cells = np.array(self.cells)
        if points.ndim != 2 or points.shape[1] != 2 or points.shape[0] < 3:
            raise ValueError(f"DiskMesh: points must have shape (n_nodes >= 3, 2), got {points.shape}")
        if not np.all(np.isfinite(points)):
            raise ValueError("DiskMesh: points must be finite")
        npc = _NODES_PER_CELL[self.element]
        if cells.ndim != 2 or cells.shape[1] != npc or cells.shape[0] < 1:
            raise ValueError(
                f"DiskMesh: cells must have shape (n_elements >= 1, {npc}) for {self.element}, "
                f"got {cells.shape}"
            )
        if not np.issubdtype(cells.dtype, np.integer):
            raise ValueError(f"DiskMesh: cells must be integers, got dtype {cells.dtype}")
        cells = cells.astype(np.int64)
        if cells.min() < 0 or cells.max() >= len(points):
            raise ValueError(f"DiskMesh: cells must index points in [0, {len(points) - 1}]")
        points.setflags(write=False)
        cells.setflags(write=False)
        object.__setattr__(self, "points", points)
        object.__setattr__(self, "cells", cells)

    # ---- sizes ------------------------------------------------------------------------------

    @property
    def n_nodes(self) -> int:
        return int(self.points.shape[0])

    @property
    def n_elements(self) -> int:
        return int(self.cells.shape[0])

    @property
    def cell_type(self) -> str:
        """meshio cell type: "triangle" (T3) or "triangle6" (T6)."""
        return ELEMENT_CELL[self.element]

    # ---- geometry ---------------------------------------------------------------------------

    @functools.cached_property
    def element_areas(self) -> np.ndarray:
        """Area of each element, shape (n_elements,): straight-sided for T3; for T6 the area of
        the quadratic (isoparametric) element, curved edges included (exact: det J is
        quadratic, integrated by a degree-2 rule)."""
        areas = signed_areas(self.points, self.cells)
        areas.setflags(write=False)
        return areas

    @property
    def area(self) -> float:
        """Total area: polygonal for T3, with curved (quadratic) edges for T6."""
        return float(self.element_areas.sum())

    @property
    def centroid(self) -> np.ndarray:
        """Area centroid of the vertex polygon mesh, shape (2,)."""
        vert = self.points[self.cells[:, :3]]
        a = signed_areas(self.points, self.cells[:, :3])
        return (a[:, None] * vert.mean(axis=1)).sum(axis=0) / a.sum()

    @functools.cached_property
    def boundary_nodes(self) -> np.ndarray:
        """Indices of all boundary nodes as one counter-clockwise loop (the domain on the
        left), shape (n_boundary,), the first node not repeated at the end. For T6 the
        midside nodes are included between their edge's vertices. Starts at the boundary
        vertex of smallest index."""
        loop = boundary_loop(self.cells, element_type(self.element))
        loop.setflags(write=False)
        return loop

    def placed(self, centre, radius: float) -> "DiskMesh":
        """A copy scaled by ``radius`` about the origin then translated by ``centre``: for a
        reference (unit, centred) mesh, the disk of that radius at that centre. Never remeshes;
        the cells array is shared (it is read-only)."""
        c = np.asarray(centre, dtype=np.float64)
        if c.shape != (2,) or not np.all(np.isfinite(c)):
            raise ValueError(f"placed: centre must be 2 finite numbers, got {centre!r}")
        r = float(radius)
        if not (math.isfinite(r) and r > 0.0):
            raise ValueError(f"placed: radius must be a finite number > 0, got {radius!r}")
        return DiskMesh(points=self.points * r + c, cells=self.cells, element=self.element)

    # ---- I/O --------------------------------------------------------------------------------

    def to_meshio(self):
        """A ``meshio.Mesh`` with 3D points (z = 0) and one cell block."""
        import meshio

        pts = np.zeros((self.n_nodes, 3))
        pts[:, :2] = self.points
        return meshio.Mesh(pts, [(self.cell_type, np.array(self.cells))])

    def write(self, path: str | os.PathLike) -> None:
        """Write to ``.vtu`` (VTK XML) or ``.msh`` (gmsh 4.1, ASCII) with meshio."""
        import meshio

        path = os.fspath(path)
        ext = os.path.splitext(path)[1].lower()
        if ext == ".msh":
            meshio.write(path, self.to_meshio(), file_format="gmsh", binary=False)
        elif ext == ".vtu":
            meshio.write(path, self.to_meshio(), file_format="vtu")
        else:
            raise ValueError(f"DiskMesh.write: {path}: extension must be .msh or .vtu, got {ext!r}")

    @classmethod
    def read(cls, path: str | os.PathLike) -> "DiskMesh":
        """Read a mesh written by :meth:`write` (or any ``.msh`` / ``.vtu`` with exactly one
        kind of triangle cells, z = 0). Unused nodes are dropped and cells reoriented CCW."""
        import meshio

        path = os.fspath(path)
        ext = os.path.splitext(path)[1].lower()
        if ext not in (".msh", ".vtu"):
            raise ValueError(f"DiskMesh.read: {path}: extension must be .msh or .vtu, got {ext!r}")
        m = meshio.read(path, file_format="gmsh" if ext == ".msh" else "vtu")
        blocks = [b for b in m.cells if b.type in CELL_ELEMENT]
        kinds = {b.type for b in blocks}
        if len(kinds) != 1:
            raise ValueError(
                f"DiskMesh.read: {path}: cells: expected one kind of 'triangle' or 'triangle6' "
                f"cells, found {sorted(kinds) or 'none'}"
            )
        element = CELL_ELEMENT[kinds.pop()]
        cells = np.concatenate([b.data for b in blocks]).astype(np.int64)
        pts = np.asarray(m.points, dtype=np.float64)
        if pts.shape[1] == 3 and np.any(np.abs(pts[:, 2]) > 1e-12 * max(1.0, np.abs(pts).max())):
            raise ValueError(f"DiskMesh.read: {path}: points: expected a 2D mesh (z = 0)")
        points, cells = _compact_and_orient(pts[:, :2], cells, element)
        return cls(points=points, cells=cells, element=element)


# --------------------------------------------------------------------------------------------
# Reference meshes
# --------------------------------------------------------------------------------------------


def _check_n_elements(n_elements) -> int:
    if isinstance(n_elements, bool):
        raise ValueError(f"n_elements must be an integer >= 4, got {n_elements!r}")
    try:
        n = operator.index(n_elements)
    except TypeError:
        raise ValueError(f"n_elements must be an integer >= 4, got {n_elements!r}") from None
    if n < 4:
        raise ValueError(f"n_elements must be an integer >= 4, got {n}")
    return n


def _check_element(element) -> str:
    if element not in ELEMENTS:
        raise ValueError(f"element must be one of {ELEMENTS} ('T3' linear, 'T6' quadratic), got {element!r}")
    return element


def reference_disk_mesh(n_elements: int = 92, element: str = "T3", boundary_segments: int | None = None) -> DiskMesh:
    """The unit-radius disk centred at the origin, meshed with about ``n_elements`` triangles
    of similar size (exactly 92 for the default: 20 boundary segments, mesh size 0.3), or
    graded toward its boundary when ``boundary_segments`` is given.

    Made once per ``(n_elements, element)`` per process (cached); the result is immutable
    (read-only arrays), use :meth:`DiskMesh.placed` for each body. Safe to call from several
    threads (gmsh runs under a lock).

    Parameters
    ----------
    n_elements : int >= 4
        Target number of triangles; the mesh has the closest count reachable with similar
        elements (within about 10 % for targets >= 30; exact at 92).
    element : "T3" | "T6"
        Linear triangles, or quadratic ones (``triangle6``) with boundary midside nodes on
        the circle; same triangulation as T3 for a given target.
    boundary_segments : int, optional
        A boundary-graded mesh, to resolve contact zones much smaller than the disk: the
        circle is split into ``boundary_segments`` equal arcs (more than the uniform mesh of
        ``n_elements`` has) and the element size grows linearly with the distance to the
        circle, by ``GRADING`` per unit length, up to the interior size of the uniform mesh
        of ``n_elements``. The element count is then larger than ``n_elements`` (T6, interior
        of 1000 elements: 240 segments -> about 2000 elements, 960 -> about 8500).

    Raises
    ------
    ValueError
        ``n_elements`` not an integer >= 4, ``element`` not "T3" / "T6", or
        ``boundary_segments`` not more than the uniform mesh's boundary segments.
    """
    n_elements, element = _check_n_elements(n_elements), _check_element(element)
    if boundary_segments is not None:
        uniform = disk_mesh_resolution(n_elements)[0]
        if not isinstance(boundary_segments, (int, np.integer)) or boundary_segments <= uniform:
            raise ValueError(f"boundary_segments must be an integer > {uniform} (the boundary segments of "
                             f"the uniform {n_elements}-element mesh), got {boundary_segments!r}")
        boundary_segments = int(boundary_segments)
    return _reference_disk_mesh(n_elements, element, boundary_segments)


@functools.lru_cache(maxsize=None)
def _reference_disk_mesh(n_elements: int, element: str, boundary_segments: int | None) -> DiskMesh:
    n_segments, size = disk_mesh_resolution(n_elements)
    order = 2 if element == "T6" else 1
    if boundary_segments is None:
        points, cells = _gmsh_disk(n_segments, size, order)
    else:
        points, cells = _gmsh_disk(boundary_segments, size, order, graded=True)
    return DiskMesh(points=points, cells=cells, element=element)


@functools.lru_cache(maxsize=None)
def disk_mesh_resolution(n_elements: int) -> tuple[int, float]:
    """``(n_segments, mesh_size)`` for a unit disk with about ``n_elements`` triangles.

    The boundary is split into ``n_segments`` equal arcs (a transfinite curve) and the interior
    mesh size is ``mesh_size`` ~ 6 / n_segments (0.955 x the boundary segment length). The
    first guess inverts the measured N ~ 0.2 n^2 + 0.5 n; a short walk in ``n`` then brackets
    the target, and for coarse meshes where counts jump a few mesh-size factors within
    +-20 % are tried. Each trial meshes once; the result is cached.
    """
    target = _check_n_elements(n_elements)
    n0 = (-_COUNT_B + math.sqrt(_COUNT_B**2 + 4.0 * _COUNT_A * target)) / (2.0 * _COUNT_A)
    n = max(4, int(round(n0)))

    def count(n_seg: int, factor: float) -> int:
        return _gmsh_disk(n_seg, factor * _SIZE_PER_SEGMENT / n_seg, 1)[1].shape[0]

    # Walk n (default size) until the count brackets the target.
    counts = {n: count(n, 1.0)}
    step = 1 if counts[n] < target else -1
    while True:
        nxt = n + step
        if nxt < 4:
            break
        counts[nxt] = count(nxt, 1.0)
        n = nxt
        if (counts[nxt] - target) * step >= 0:
            break
    candidates = {(k, 1.0): v for k, v in counts.items()}

    def best():
        return min(
            candidates.items(),
            key=lambda kv: (abs(kv[1] - target), _SIZE_FACTORS.index(kv[0][1]), abs(kv[0][0] - n0)),
        )

    (n_best, f_best), c_best = best()
    if abs(c_best - target) > _GOOD_ENOUGH * target:
        bracket = sorted({k for k, v in counts.items()}, key=lambda k: abs(counts[k] - target))[:2]
        for k in bracket:
            for f in _SIZE_FACTORS[1:]:
                candidates[(k, f)] = count(k, f)
        (n_best, f_best), c_best = best()
    return n_best, f_best * _SIZE_PER_SEGMENT / n_best


def _grade_from_boundary(curves: list[int], boundary_size: float, size: float, sampling: int) -> None:
    """Background size field of the current gmsh model: boundary_size on ``curves``, growing
    linearly with the distance by GRADING up to ``size`` (the boundary no longer sets sizes)."""
    import gmsh

    field = gmsh.model.mesh.field
    distance = field.add("Distance")
    field.setNumbers(distance, "CurvesList", curves)
    field.setNumber(distance, "Sampling", sampling)
    threshold = field.add("Threshold")
    field.setNumber(threshold, "InField", distance)
    field.setNumber(threshold, "SizeMin", boundary_size)
    field.setNumber(threshold, "SizeMax", size)
    field.setNumber(threshold, "DistMin", 0.0)
    field.setNumber(threshold, "DistMax", max(size - boundary_size, 0.0) / GRADING)
    field.setAsBackgroundMesh(threshold)
    gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0.0)


def clear_mesh_cache() -> None:
    """Forget every cached reference mesh, resolution and gmsh result."""
    _reference_disk_mesh.cache_clear()
    disk_mesh_resolution.cache_clear()
    _gmsh_disk.cache_clear()


# --------------------------------------------------------------------------------------------
# gmsh
# --------------------------------------------------------------------------------------------


@functools.lru_cache(maxsize=64)
def _gmsh_disk(n_segments: int, size: float, order: int, graded: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Mesh the unit disk with gmsh: boundary circle = one transfinite curve with
    ``n_segments + 1`` points, interior mesh size ``size``, element order 1 or 2; if
    ``graded``, the size grows from the boundary segment length by GRADING per unit distance to
    the circle (a Distance + Threshold background field) up to ``size``.

    Returns read-only ``points (n, 2)`` (used nodes only, renumbered in gmsh tag order) and
    ``cells (ne, 3 | 6)`` (CCW, meshio order)."""
    import gmsh

    with _GMSH_LOCK:
        owns = not gmsh.isInitialized()
        saved = {}
        if owns:
            gmsh.initialize(interruptible=False)
        try:
            for name, value in _PINNED_OPTIONS.items():
                if not owns:
                    saved[name] = gmsh.option.getNumber(name)
                gmsh.option.setNumber(name, value)
            if not owns:
                saved["Mesh.MeshSizeMax"] = gmsh.option.getNumber("Mesh.MeshSizeMax")
                previous_model = gmsh.model.getCurrent()
            gmsh.option.setNumber("Mesh.MeshSizeMax", float(size))
            gmsh.model.add("softrigid_unit_disk")
            try:
                disk = gmsh.model.occ.addDisk(0.0, 0.0, 0.0, 1.0, 1.0)
                gmsh.model.occ.synchronize()
                curves = [curve for _, curve in gmsh.model.getBoundary([(2, disk)], oriented=False)]
                for curve in curves:
                    gmsh.model.mesh.setTransfiniteCurve(curve, int(n_segments) + 1)
                if graded:
                    _grade_from_boundary(curves, 2.0 * math.pi / n_segments, size, 4 * n_segments)
                gmsh.model.mesh.generate(2)
                if order == 2:
                    gmsh.model.mesh.setOrder(2)
                elem_type = gmsh.model.mesh.getElementType("Triangle", order)
                _, node_tags = gmsh.model.mesh.getElementsByType(elem_type)
                tags, coords, _ = gmsh.model.mesh.getNodes()
            finally:
                gmsh.model.remove()
                if not owns and previous_model:
                    gmsh.model.setCurrent(previous_model)
        finally:
            if owns:
                gmsh.finalize()
            else:
                for name, value in saved.items():
                    gmsh.option.setNumber(name, value)

    element = "T6" if order == 2 else "T3"
    npc = _NODES_PER_CELL[element]
    tags = np.asarray(tags, dtype=np.int64)
    coords = np.asarray(coords, dtype=np.float64).reshape(-1, 3)
    conn_tags = np.asarray(node_tags, dtype=np.int64).reshape(-1, npc)
    # gmsh tags -> positions in the getNodes arrays
    order_by_tag = np.argsort(tags, kind="stable")
    coords = coords[order_by_tag]
    lookup = np.full(tags.max() + 1, -1, dtype=np.int64)
    lookup[tags[order_by_tag]] = np.arange(len(tags))
    cells = lookup[conn_tags]
    if np.any(cells < 0):
        raise RuntimeError("gmsh returned elements referencing unknown nodes")
    points, cells = _compact_and_orient(coords[:, :2], cells, element)
    points.setflags(write=False)
    cells.setflags(write=False)
    return points, cells


# --------------------------------------------------------------------------------------------
# Mesh helpers (pure numpy)
# --------------------------------------------------------------------------------------------


def _compact_and_orient(points: np.ndarray, cells: np.ndarray, element: str):
    """Drop nodes no cell uses (keeping the order of the others), renumber, and flip clockwise
    triangles (vertex order 0, 2, 1; T6 midside nodes 5, 4, 3)."""
    used = np.unique(cells)
    remap = np.full(len(points), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    points = np.ascontiguousarray(points[used], dtype=np.float64)
    cells = remap[cells]
    cw = signed_areas(points, cells[:, :3]) < 0.0  # the vertex triangles
    if np.any(cw):
        perm = [0, 2, 1] if element == "T3" else [0, 2, 1, 5, 4, 3]
        cells[cw] = cells[cw][:, perm]
    return points, np.ascontiguousarray(cells, dtype=np.int64)
