"""Topology and geometry of triangle meshes, on the reference elements of :mod:`compute.fem.elements`:
the boundary loop of a disk mesh and the element areas (exact for the curved edges of T6). One
implementation for the three stages: pre's meshes, compute's bodies, post's measures.
"""

from __future__ import annotations

import numpy as np

from compute.fem.elements import T3, T6, ElementType

__all__ = ["boundary_loop", "signed_areas"]


def signed_areas(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Areas (n_cells,) of the T3 or T6 triangles ``cells`` (n_cells, 3 | 6) of ``points``
    (n_points, 2): the integral of det J over the reference triangle, positive for
    counter-clockwise cells; for T6 the area bounded by the three parabolic edges (det J is
    quadratic, integrated exactly by the element's degree-2 rule)."""
    element = T3 if cells.shape[1] == 3 else T6
    rule = element.stiffness_rule
    _, dN = element.basis(rule.points)                                   # (q, nodes, 2)
    jacobian = np.einsum("qka,ekd->eqda", dN, points[cells])             # dx_d / dxi_a
    det = jacobian[..., 0, 0] * jacobian[..., 1, 1] - jacobian[..., 0, 1] * jacobian[..., 1, 0]
    return det @ rule.weights


def boundary_loop(cells: np.ndarray, element: ElementType) -> np.ndarray:
    """All boundary nodes (corners and, for T6, midside nodes) as one closed CCW loop, (n_b,).

    cells (n_elem, n_en) must be counter-clockwise. The loop starts at the smallest boundary
    corner index and does not repeat it at the end; segment k joins loop[k] and loop[k+1 mod n_b]
    (for T6 each element edge is split into two straight sub-segments at its midside node).
    Raises ValueError if the boundary is not a single closed curve (holes, several parts,
    non-manifold edges).
    """
    edges = cells[:, element.edges].reshape(-1, element.edges.shape[1])
    key = np.sort(edges[:, [0, -1]], axis=1)
    _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    if counts.max() > 2:
        raise ValueError("mesh has edges shared by more than two elements")
    boundary = edges[counts[inverse.ravel()] == 1]
    successor = {int(edge[0]): edge for edge in boundary}
    if len(successor) != len(boundary):
        raise ValueError("mesh boundary touches itself (a corner starts two boundary edges)")
    start = node = min(successor)
    loop: list[int] = []
    for _ in range(len(boundary)):
        edge = successor[node]
        loop.extend(int(n) for n in edge[:-1])
        node = int(edge[-1])
        if node == start:
            break
    if node != start or len(loop) != boundary.size - len(boundary):
        raise ValueError("mesh boundary is not a single closed loop (holes or several parts)")
    return np.array(loop, dtype=np.int64)
