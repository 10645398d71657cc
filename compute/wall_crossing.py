"""How far the soft bodies' boundaries cross the walls, between their nodes included.

The wall contacts hold a soft body's boundary nodes (compute/contact, node–wall rows). A T3 edge
is straight, so it stays inside the box with its two nodes; a T6 edge is a parabola through its
two corners and its midside node, and bulges past a wall between them when its nodes sit on
the wall at different depths of the curve. The body's area (the exact area inside the curved
edges, compute.fem.topology) then counts what lies beyond the walls, and φ passes 1.

On the single particle the nodes stay on the walls to round-off while the curved edges cross
them at every stage, and the area beyond the walls is exactly φ - 1 where φ passes 1 (figures:
benchmarks/results/design_figures.md). compute.run stops a run whose φ passes 1 with this
diagnosis.
"""

from __future__ import annotations

import numpy as np

WALL_NAMES = ("xmin", "xmax", "ymin", "ymax")
CROSSING_LIMIT = 1e-4  # of the body's radius: deeper than the contact tolerance lets a node go, far
# shallower than the curved edges' crossing (design_figures.md)


def _edge_extremes(x0: np.ndarray, xm: np.ndarray, x2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Smallest and largest value, over s in [0, 1], of the parabola through x0 (s = 0), xm
    (s = 1/2) and x2 (s = 1), per edge and coordinate (arrays of one shape)."""
    b, c = -3.0 * x0 + 4.0 * xm - x2, 2.0 * x0 - 4.0 * xm + 2.0 * x2
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.clip(np.where(c != 0.0, -b / (2.0 * c), 0.0), 0.0, 1.0)
    xs = x0 + b * s + c * s * s
    return np.minimum(np.minimum(x0, x2), xs), np.maximum(np.maximum(x0, x2), xs)


def deepest_crossing(model, q: np.ndarray) -> tuple[float, str, int, bool]:
    """(depth, wall name, body id, at a node) of the soft boundary point farthest beyond a wall
    (depth <= 0 when every boundary point is inside the box); ``at a node``: the deepest point
    is a node, not a point of a curved edge between nodes."""
    bounds = model.bounds(q)
    best = (-np.inf, WALL_NAMES[0], -1, True)
    for g in model.soft:
        x = g.nodes(q)[:, g.batch.boundary]  # (B, n_b, 2), the closed CCW loop
        step = 2 if g.batch.element.name == "T6" else 1  # T6: corner, midside, corner, ...
        corners = x[:, ::step]
        nxt = np.roll(corners, -1, axis=1)
        mid = x[:, 1::2] if step == 2 else 0.5 * (corners + nxt)
        low, high = _edge_extremes(corners, mid, nxt)  # (B, n_edges, 2)
        depths = np.stack([bounds[0] - low[..., 0], high[..., 0] - bounds[1],
                           bounds[2] - low[..., 1], high[..., 1] - bounds[3]])  # (4, B, n_edges)
        w, b, _ = np.unravel_index(np.argmax(depths), depths.shape)
        if depths[w, b].max() > best[0]:
            node_depths = np.array([bounds[0] - x[b, :, 0], x[b, :, 0] - bounds[1],
                                    bounds[2] - x[b, :, 1], x[b, :, 1] - bounds[3]])[w]
            at_node = bool(node_depths.max() >= depths[w, b].max())
            best = (float(depths[w, b].max()), WALL_NAMES[w], int(g.ids[b]), at_node)
    return best


def crossed(model, q: np.ndarray) -> bool:
    """Whether some soft boundary lies beyond a wall by more than CROSSING_LIMIT of its radius:
    the area beyond the walls that makes φ pass 1. (φ may also pass 1 by a few 1e-5 in a mixture
    near φ = 1 without it: bodies overlapping within the contact tolerance, rigid disks' arcs
    inside the soft polygons between their nodes, count twice.)"""
    depth, _, body, _ = deepest_crossing(model, q)
    return body >= 0 and depth > CROSSING_LIMIT * float(model.scene.radius[body])


def diagnosis(model, q: np.ndarray, phi: float) -> str:
    """Why φ passed 1: where the soft boundaries cross the walls (module docstring) and what to
    change."""
    depth, wall, body, at_node = deepest_crossing(model, q)
    if depth <= 0.0:
        return f"phi = {phi:.6f} > 1 with every soft boundary inside the box (a folded element?)"
    radius = float(model.scene.radius[body])
    where = "at a node" if at_node else "between its nodes (its curved T6 edges: the wall contacts hold the nodes only)"
    return (f"phi = {phi:.6f} > 1: body {body}'s boundary crosses wall {wall} by {depth:.3g} ({depth / radius:.2g} "
            f"of its radius) {where}; phi counts the area beyond the walls. Use T3 elements (straight edges) or "
            f"pressures below this one")
