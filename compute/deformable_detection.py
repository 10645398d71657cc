"""Detection for deformable boundaries: Verlet candidate lists, warm-start memory, narrow phase.

Families (kept in ``state.pairs`` / ``state.impulses`` after the rigid ones of
:mod:`compute.detection`, which keeps its own ``disk_disk`` and ``disk_wall``):

- ``node_wall``    (m, 2): (global node, wall 0..3);
- ``node_disk``    (m, 2): (global node, local rigid-disk index);
- ``node_segment`` (m, 3): (global node, deformable index of the antagonist body, segment hint).

Broad phase, O(N): bounding circles of every body (rigid disks; deformable boundary loops with
their current centre and maximum radius) go through :func:`compute.broadphase.disk_pairs` and
:func:`compute.broadphase.wall_pairs` with the skin; node-level candidates are then searched
only inside those body pairs (:mod:`compute.deformable_contacts`). The lists are rebuilt only
when a rigid centre or a boundary node has moved more than half the skin since the last
detection (or a wall and a body together more than the skin); impulses of candidates that
survive a rebuild are kept (warm start), matched on (node, antagonist).
"""

from __future__ import annotations

import numpy as np

from compute import broadphase, detection
from compute.contact_geometry import WALL_AXES, WALL_NORMALS, Contacts
from compute.deformable_contacts import (
    near_disk_nodes,
    near_segment_nodes,
    near_wall_nodes,
    node_disk_rows,
    node_segment_rows,
    node_wall_rows,
)
from compute.state import State

FAMILIES = ("node_wall", "node_disk", "node_segment")


def needs_detection(model, state: State) -> bool:
    """True when the lists are missing or something moved past the Verlet criterion."""
    if state.q_detect is None or any(f not in state.pairs for f in (*detection.FAMILIES, *FAMILIES)):
        return True
    skin = detection.skin_distance(model)
    dr = model.rigid_view(state.q)[:, :2] - model.rigid_view(state.q_detect)[:, :2]
    loop = model.loop_nodes
    dn = model.node_positions(state.q)[loop] - model.node_positions(state.q_detect)[loop]
    d2 = 0.0
    if len(dr):
        d2 = max(d2, float(np.max(np.sum(dr**2, axis=1))))
    if len(dn):
        d2 = max(d2, float(np.max(np.sum(dn**2, axis=1))))
    dmax = np.sqrt(d2)
    wmax = float(np.max(np.abs(model.bounds(state.q) - model.bounds(state.q_detect))))
    return 2.0 * dmax > skin or dmax + wmax > skin


def detect(model, state: State) -> None:
    """Rebuild every candidate list (rigid families through compute.detection) in place."""
    detection.detect(model, state)  # rigid families; sets state.q_detect
    skin = detection.skin_distance(model)
    x = model.node_positions(state.q)
    c_def, r_def = model.bounding_circles(x)
    nr = model.layout.n_rigid
    centres = np.vstack([model.rigid_view(state.q)[:, :2], c_def])
    radii = np.concatenate([model.radii, r_def])
    pairs = broadphase.disk_pairs(np.ascontiguousarray(centres), radii, skin)
    a, b = pairs[:, 0], pairs[:, 1]
    mixed = (a < nr) & (b >= nr)
    body_disks = np.ascontiguousarray(np.column_stack([b[mixed] - nr, a[mixed]]), dtype=np.int64)
    both = a >= nr
    body_pairs = np.ascontiguousarray(np.column_stack([a[both] - nr, b[both] - nr]), dtype=np.int64)
    bounds = np.ascontiguousarray(model.bounds(state.q))
    body_walls = broadphase.wall_pairs(c_def, r_def, bounds, skin)
    rig_c = np.ascontiguousarray(model.rigid_view(state.q)[:, :2])
    new = {
        "node_wall": near_wall_nodes(body_walls, x, model.loop_nodes, model.loop_start, bounds, WALL_NORMALS, skin),
        "node_disk": near_disk_nodes(body_disks, x, model.loop_nodes, model.loop_start, rig_c, model.radii, skin),
        "node_segment": near_segment_nodes(body_pairs, x, model.loop_nodes, model.loop_start, c_def, r_def, skin),
    }
    for fam, p in new.items():
        state.impulses[fam] = carry(state.pairs.get(fam), state.impulses.get(fam), p)
        state.pairs[fam] = p


def carry(old_pairs, old_impulses, pairs: np.ndarray) -> np.ndarray:
    """Impulses (m, 2) for ``pairs`` (m, >= 2) from the old list, matched on the first two columns."""
    out = np.zeros((len(pairs), 2))
    if old_pairs is None or len(old_pairs) == 0 or len(pairs) == 0:
        return out
    base = int(max(old_pairs[:, :2].max(), pairs[:, :2].max())) + 1
    old_keys = old_pairs[:, 0] * base + old_pairs[:, 1]
    keys = pairs[:, 0] * base + pairs[:, 1]
    order = np.argsort(old_keys)
    idx = np.minimum(np.searchsorted(old_keys[order], keys), len(order) - 1)
    found = old_keys[order][idx] == keys
    out[found] = old_impulses[order[idx[found]]]
    return out


def narrow_phase(model, state: State, centres: np.ndarray | None = None) -> Contacts:
    """Contacts of the deformable families at ``state.q`` (impulses from the memory).

    ``centres`` (n_bodies, 2): body centres for the branch vectors (``model.body_centres``).
    """
    q = state.q
    x = model.node_positions(q)
    if centres is None:
        centres = model.body_centres(q)
    lay = model.layout
    nd0 = model.node_dof0
    parts = []

    p = state.pairs["node_wall"]
    c = Contacts.empty(len(p))
    node_wall_rows(p, x, nd0, np.ascontiguousarray(model.bounds(q)), lay.wall_dof0, WALL_NORMALS, WALL_AXES,
                   c.dof, c.hn, c.ht, c.gap, c.normal, c.point)
    c.pairs[:] = p
    c.body_i[:] = model.deformable_ids[model.node_body[p[:, 0]]]
    c.body_j[:] = -1 - p[:, 1]
    c.branch[:] = c.point - centres[c.body_i]
    parts.append(c)

    p = state.pairs["node_disk"]
    c = Contacts.empty(len(p))
    node_disk_rows(p, x, nd0, np.ascontiguousarray(model.rigid_view(q)[:, :2]), model.radii, lay.rigid_dof0(),
                   c.dof, c.hn, c.ht, c.gap, c.normal, c.point)
    c.pairs[:] = p
    k = model.node_body[p[:, 0]]
    c.body_i[:] = model.deformable_ids[k]
    c.body_j[:] = model.rigid_ids[p[:, 1]]
    c.mu[:] = model.friction[model.deformable_material[k], model.rigid_material[p[:, 1]]]
    c.branch[:] = centres[c.body_j] - centres[c.body_i]
    parts.append(c)

    p = state.pairs["node_segment"]
    c = Contacts.empty(len(p))
    node_segment_rows(p, x, nd0, model.loop_nodes, model.loop_start, c.dof, c.hn, c.ht, c.gap, c.normal, c.point)
    c.pairs[:] = p[:, :2]
    k = model.node_body[p[:, 0]]
    c.body_i[:] = model.deformable_ids[k]
    c.body_j[:] = model.deformable_ids[p[:, 1]]
    c.mu[:] = model.friction[model.deformable_material[k], model.deformable_material[p[:, 1]]]
    c.branch[:] = centres[c.body_j] - centres[c.body_i]
    parts.append(c)

    out = Contacts.concatenate(parts)
    # entries that carry no impulse (zero normal row, and a zero tangential row or no friction)
    # are dropped: the dense compliance blocks then cover fewer dofs (half of them for walls)
    idle = (out.hn == 0.0) & ((out.mu == 0.0)[:, None] | (out.ht == 0.0))
    out.dof[idle] = -1
    out.impulse[:] = np.concatenate([state.impulses[f] for f in FAMILIES]) if len(out) else np.zeros((0, 2))
    return out


def store_impulses(state: State, impulse: np.ndarray) -> None:
    """Write solved impulses (m, 2) back to the memory of the deformable families, in the order
    of :func:`narrow_phase`."""
    k = 0
    for fam in FAMILIES:
        m = len(state.pairs[fam])
        state.impulses[fam] = impulse[k:k + m].copy()
        k += m
