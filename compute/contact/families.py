"""The registry of contact families: for each pair of body kinds, how candidates are found and
how their rows (gap, frame, rows of H) are made.

A family is ``Family(name, kinds, candidates, rows)``:

- ``candidates(model, q, broad, skin)`` -> (m, k) int64 candidate list, k >= 2, whose first two
  columns identify a contact (impulses are carried over a re-detection on them);
- ``rows(model, q, pairs, centres)`` -> :class:`~compute.contact.rows.ContactRows` at q
  (``centres`` (n_bodies, 2): body centres for the branch vectors, or None when the caller does
  not need branches: a step does not); a family may update ``pairs`` in place (a
  closest-segment hint).

``broad`` is the shared broad phase of one detection (:class:`Broad`): candidate pairs of body
bounding circles (rigid disks, then soft boundary loops) and of circles and walls. A new body
kind adds its families here (e.g. soft polygons: node-to-segment rows already cover them).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from compute.contact import broadphase
from compute.contact.rows import WALL_AXES, WALL_NORMALS, ContactRows, disk_disk_rows, disk_wall_rows
from compute.contact.soft_rows import (
    near_disk_nodes,
    near_segment_disks,
    near_segment_nodes,
    near_wall_nodes,
    node_disk_rows,
    node_segment_rows,
    node_wall_rows,
    segment_disk_rows,
)


@dataclass(frozen=True)
class Family:
    name: str
    kinds: tuple[str, str]
    candidates: Callable
    rows: Callable


class Broad:
    """Broad phase of one detection: circles (rigid disks then soft bodies' boundary loops),
    ``pairs`` (p, 2) of circles within the skin (i < j) and ``walls`` (w, 2) of (circle, wall)."""

    def __init__(self, model, q, skin: float):
        self.n_rigid = len(model.rigid)
        c_soft, r_soft = model.soft_circles(q)
        self.soft_centres, self.soft_radii = c_soft, r_soft
        centres = np.ascontiguousarray(np.vstack([model.rigid.centres(q), c_soft]))
        radii = np.concatenate([model.rigid.radii, r_soft])
        self.pairs = broadphase.disk_pairs(centres, radii, skin)
        self.walls = broadphase.wall_pairs(centres, radii, np.ascontiguousarray(model.walls.bounds(q)), skin)

    def select(self, a_soft: bool, b_soft: bool, pairs: np.ndarray) -> np.ndarray:
        """Pairs (m, 2) of ``pairs`` whose first is soft iff a_soft and second iff b_soft, renumbered
        within each kind (rigid index, soft index); a mixed pair is put in the asked order."""
        nr = self.n_rigid
        a, b = pairs[:, 0], pairs[:, 1]
        sa, sb = a >= nr, b >= nr
        keep = (sa == a_soft) & (sb == b_soft)
        out = np.column_stack([a[keep], b[keep]])
        if a_soft != b_soft:
            swap = (sb == a_soft) & (sa == b_soft)
            out = np.vstack([out, np.column_stack([b[swap], a[swap]])])
        out = out - nr * np.array([a_soft, b_soft])
        return np.ascontiguousarray(out, dtype=np.int64)


# --- rigid disk families ----------------------------------------------------------------------


def _disk_disk_candidates(model, q, broad, skin):
    return broad.select(False, False, broad.pairs)


def _disk_disk_rows(model, q, pairs, centres):
    r = model.rigid
    c = ContactRows.empty(len(pairs))
    disk_disk_rows(pairs, np.ascontiguousarray(r.centres(q)), r.radii, r.dof_of(), c.dof, c.hn, c.ht, c.gap,
                   c.normal, c.point, c.branch)
    c.pairs[:] = pairs
    c.body_i[:] = r.ids[pairs[:, 0]]
    c.body_j[:] = r.ids[pairs[:, 1]]
    c.mu[:] = model.friction[r.material[pairs[:, 0]], r.material[pairs[:, 1]]]
    return c


def _disk_wall_candidates(model, q, broad, skin):
    w = broad.walls
    return np.ascontiguousarray(w[w[:, 0] < broad.n_rigid], dtype=np.int64)


def _disk_wall_rows(model, q, pairs, centres):
    r, walls = model.rigid, model.walls
    c = ContactRows.empty(len(pairs))
    disk_wall_rows(pairs, np.ascontiguousarray(r.centres(q)), r.radii, r.dof_of(),
                   np.ascontiguousarray(walls.bounds(q)), walls.dof0, WALL_NORMALS, WALL_AXES,
                   c.dof, c.hn, c.ht, c.gap, c.normal, c.point, c.branch)
    c.pairs[:] = pairs
    c.body_i[:] = r.ids[pairs[:, 0]]
    c.body_j[:] = -1 - pairs[:, 1]
    return c


# --- soft boundary families (node-level candidates inside the body pairs) -------------------


def _node_wall_candidates(model, q, broad, skin):
    w = broad.walls
    body_walls = np.ascontiguousarray(w[w[:, 0] >= broad.n_rigid] - [broad.n_rigid, 0], dtype=np.int64)
    return near_wall_nodes(body_walls, model.soft_nodes(q), model.loop_nodes, model.loop_start,
                           np.ascontiguousarray(model.walls.bounds(q)), WALL_NORMALS, skin)


def _node_wall_rows(model, q, pairs, centres):
    c = ContactRows.empty(len(pairs))
    node_wall_rows(pairs, model.soft_nodes(q), model.node_dof0, np.ascontiguousarray(model.walls.bounds(q)),
                   model.walls.dof0, WALL_NORMALS, WALL_AXES, c.dof, c.hn, c.ht, c.gap, c.normal, c.point)
    c.pairs[:] = pairs
    c.body_i[:] = model.soft_ids[model.node_body[pairs[:, 0]]]
    c.body_j[:] = -1 - pairs[:, 1]
    if centres is not None:
        c.branch[:] = c.point - centres[c.body_i]
    return c


def _node_disk_candidates(model, q, broad, skin):
    body_disks = broad.select(True, False, broad.pairs)
    return near_disk_nodes(body_disks, model.soft_nodes(q), model.loop_nodes, model.loop_start,
                           np.ascontiguousarray(model.rigid.centres(q)), model.rigid.radii, skin)


def _node_disk_rows(model, q, pairs, centres):
    r = model.rigid
    c = ContactRows.empty(len(pairs))
    node_disk_rows(pairs, model.soft_nodes(q), model.node_dof0, np.ascontiguousarray(r.centres(q)), r.radii,
                   r.dof_of(), c.dof, c.hn, c.ht, c.gap, c.normal, c.point)
    return _node_body_pairs(model, c, pairs, r.ids[pairs[:, 1]], r.material[pairs[:, 1]], centres)


def _segment_disk_candidates(model, q, broad, skin):
    body_disks = broad.select(True, False, broad.pairs)
    return near_segment_disks(body_disks, model.soft_nodes(q), model.loop_nodes, model.loop_start,
                              np.ascontiguousarray(model.rigid.centres(q)), model.rigid.radii, skin)


def _segment_disk_rows(model, q, pairs, centres):
    r = model.rigid
    c = ContactRows.empty(len(pairs))
    segment_disk_rows(pairs, model.soft_nodes(q), model.node_dof0, model.loop_neighbours,
                      np.ascontiguousarray(r.centres(q)), r.radii, r.dof_of(), c.dof, c.hn, c.ht, c.gap, c.normal,
                      c.point)
    return _node_body_pairs(model, c, pairs, r.ids[pairs[:, 1]], r.material[pairs[:, 1]], centres)


def _node_segment_candidates(model, q, broad, skin):
    body_pairs = broad.select(True, True, broad.pairs)
    return near_segment_nodes(body_pairs, model.soft_nodes(q), model.loop_nodes, model.loop_start,
                              broad.soft_centres, broad.soft_radii, skin)


def _node_segment_rows(model, q, pairs, centres):
    c = ContactRows.empty(len(pairs))
    node_segment_rows(pairs, model.soft_nodes(q), model.node_dof0, model.loop_nodes, model.loop_start,
                      model.loop_neighbours, c.dof, c.hn, c.ht, c.gap, c.normal, c.point)
    return _node_body_pairs(model, c, pairs[:, :2], model.soft_ids[pairs[:, 1]], model.soft_material[pairs[:, 1]],
                            centres)


def _node_body_pairs(model, c, pairs, body_j, material_j, centres):
    """Label the contacts ``c`` of (soft node, body) ``pairs`` (m, 2): bodies, friction, branch
    vectors (centre to centre) when ``centres`` is given; ``body_j``, ``material_j`` (m,) of the
    other bodies."""
    c.pairs[:] = pairs
    k = model.node_body[pairs[:, 0]]
    c.body_i[:] = model.soft_ids[k]
    c.body_j[:] = body_j
    c.mu[:] = model.friction[model.soft_material[k], material_j]
    if centres is not None:
        c.branch[:] = centres[c.body_j] - centres[c.body_i]
    return c


REGISTRY = (
    Family("disk_disk", ("rigid", "rigid"), _disk_disk_candidates, _disk_disk_rows),
    Family("disk_wall", ("rigid", "wall"), _disk_wall_candidates, _disk_wall_rows),
    Family("node_wall", ("soft", "wall"), _node_wall_candidates, _node_wall_rows),
    Family("node_disk", ("soft", "rigid"), _node_disk_candidates, _node_disk_rows),
    Family("segment_disk", ("soft", "rigid"), _segment_disk_candidates, _segment_disk_rows),
    Family("node_segment", ("soft", "soft"), _node_segment_candidates, _node_segment_rows),
)


OPTIONAL = {"segment_disk": "nodes_and_segments"}  # family -> the solver.rigid_soft_rows that asks for it


def families_of(kinds: set[str], rigid_soft_rows: str = "nodes") -> tuple[Family, ...]:
    """The families whose two kinds are both present in a model with body kinds ``kinds``; the
    optional ones (``OPTIONAL``) only with the scene's ``rigid_soft_rows`` that asks for them."""
    return tuple(f for f in REGISTRY
                 if set(f.kinds) <= kinds and OPTIONAL.get(f.name, rigid_soft_rows) == rigid_soft_rows)
