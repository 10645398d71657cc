"""Small hand-made meshes for the FE tests (no gmsh): squares, polygonal disks, T3 -> T6.

Every function returns (X (n_nodes, 2), cells (n_elem, 3 | 6)) with counter-clockwise cells.
"""

from __future__ import annotations

import numpy as np


def square_mesh(n: int, jitter: float = 0.0, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Unit square split in n x n cells, each cut into two T3 along alternating diagonals.

    Interior nodes are moved by up to ``jitter`` times the spacing (irregular patch); the
    boundary nodes stay on the sides of the square.
    """
    t = np.linspace(0.0, 1.0, n + 1)
    X = np.stack(np.meshgrid(t, t, indexing="xy"), axis=-1).reshape(-1, 2)
    interior = (X > 0.0).all(axis=1) & (X < 1.0).all(axis=1)
    rng = np.random.default_rng(seed)
    X[interior] += jitter / n * rng.uniform(-1.0, 1.0, (interior.sum(), 2))
    cells = []
    for j in range(n):
        for i in range(n):
            a, d = j * (n + 1) + i, (j + 1) * (n + 1) + i  # lower-left, upper-left corners
            b, c = a + 1, d + 1
            cells += [[a, b, c], [a, c, d]] if (i + j) % 2 == 0 else [[a, b, d], [b, c, d]]
    return X, np.array(cells)


def disk_mesh(rings: int, radius: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Polygonal disk: a centre node and rings k = 1..rings of 6k nodes on circles k/rings * radius.

    6 rings**2 T3 elements (hexagonal-ring pattern); the outer ring lies on the circle.
    """
    X = [np.zeros((1, 2))]
    ring = [np.zeros(1, dtype=int)]  # node indices of each ring, counter-clockwise
    for k in range(1, rings + 1):
        angle = 2.0 * np.pi * np.arange(6 * k) / (6 * k)
        X.append(radius * k / rings * np.column_stack([np.cos(angle), np.sin(angle)]))
        ring.append(ring[-1][-1] + 1 + np.arange(6 * k))
    cells = []
    for k in range(1, rings + 1):
        inner, outer = np.resize(ring[k - 1], 6 * k), np.append(ring[k], ring[k][0])
        for s in range(6):  # sector s: k triangles on the outer ring, k - 1 on the inner one
            i, o = s * (k - 1), s * k
            cells += [[outer[o + j], outer[o + j + 1], inner[i + j]] for j in range(k)]
            cells += [[inner[i + j], outer[o + j + 1], inner[i + j + 1]] for j in range(k - 1)]
    return np.vstack(X), np.array(cells)


def to_t6(
    X: np.ndarray, cells: np.ndarray, circle_radius: float | None = None, jitter: float = 0.0,
    seed: int = 0,
) -> tuple[np.ndarray, np.ndarray]:
    """T6 mesh from a T3 one: a midside node per edge, node order corners then edges 01, 12, 20.

    circle_radius: if given, the midside nodes of boundary edges are projected radially onto
    that circle (curved boundary elements, as gmsh does for a disk). jitter: interior midside
    nodes are moved by up to this fraction of their edge length (curved interior elements).
    """
    local = np.array([[0, 1], [1, 2], [2, 0]])
    edges = np.sort(cells[:, local], axis=2).reshape(-1, 2)
    unique, inverse, counts = np.unique(edges, axis=0, return_inverse=True, return_counts=True)
    mid = 0.5 * (X[unique[:, 0]] + X[unique[:, 1]])
    length = np.linalg.norm(X[unique[:, 0]] - X[unique[:, 1]], axis=1)
    rng = np.random.default_rng(seed)
    interior = counts == 2
    mid[interior] += jitter * length[interior, None] * rng.uniform(-1.0, 1.0, (interior.sum(), 2))
    if circle_radius is not None:
        boundary = counts == 1
        mid[boundary] *= circle_radius / np.linalg.norm(mid[boundary], axis=1)[:, None]
    midside = X.shape[0] + inverse.reshape(-1, 3)
    return np.vstack([X, mid]), np.hstack([cells, midside])


def mesh(element: str, kind: str) -> tuple[np.ndarray, np.ndarray]:
    """Test meshes by name: kind "patch" (irregular 4x4 square, curved interior T6 edges) or
    "disk" (2-ring disk, 24 elements, curved boundary for T6)."""
    if kind == "patch":
        X, cells = square_mesh(4, jitter=0.3, seed=1)
        return (X, cells) if element == "T3" else to_t6(X, cells, jitter=0.05, seed=2)
    X, cells = disk_mesh(2)
    return (X, cells) if element == "T3" else to_t6(X, cells, circle_radius=1.0)
