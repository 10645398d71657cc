"""Contact detection: Verlet candidate lists per contact family, warm-start memory, narrow phase.

Families: ``disk_disk`` (pairs of rigid disks, local indices) and ``disk_wall`` (disk, wall).
Candidates are re-detected only when a body has moved more than half the skin since the last
detection; impulses of candidates that survive a re-detection are kept (warm start).
"""

from __future__ import annotations

import numpy as np

from compute import broadphase
from compute.contact_geometry import WALL_AXES, WALL_NORMALS, Contacts, disk_disk_rows, disk_wall_rows
from compute.model import Model
from compute.state import State

FAMILIES = ("disk_disk", "disk_wall")


def skin_distance(model: Model) -> float:
    return model.scene.solver.skin * model.diameter


def needs_detection(model: Model, state: State) -> bool:
    """True when some body moved more than half the skin since the last detection."""
    if state.q_detect is None:
        return True
    skin = skin_distance(model)
    dr = model.rigid_view(state.q)[:, :2] - model.rigid_view(state.q_detect)[:, :2]
    dmax = float(np.sqrt(np.max(np.sum(dr**2, axis=1)))) if len(dr) else 0.0
    wmax = float(np.max(np.abs(model.bounds(state.q) - model.bounds(state.q_detect))))
    return 2.0 * dmax > skin or dmax + wmax > skin


def detect(model: Model, state: State) -> None:
    """Rebuild the candidate lists of ``state`` in place, keeping impulses of surviving pairs."""
    skin = skin_distance(model)
    centres = np.ascontiguousarray(model.rigid_view(state.q)[:, :2])
    new = {
        "disk_disk": broadphase.disk_pairs(centres, model.radii, skin),
        "disk_wall": broadphase.wall_pairs(centres, model.radii, model.bounds(state.q), skin),
    }
    for fam, pairs in new.items():
        state.impulses[fam] = _carry(state.pairs.get(fam), state.impulses.get(fam), pairs)
        state.pairs[fam] = pairs
    state.q_detect = state.q.copy()


def _carry(old_pairs, old_impulses, pairs: np.ndarray) -> np.ndarray:
    """Impulses (m, 2) for ``pairs`` taken from the old list where the pair existed."""
    out = np.zeros((len(pairs), 2))
    if old_pairs is None or len(old_pairs) == 0 or len(pairs) == 0:
        return out
    base = int(max(old_pairs.max(), pairs.max())) + 1
    old_keys = old_pairs[:, 0] * base + old_pairs[:, 1]
    keys = pairs[:, 0] * base + pairs[:, 1]
    order = np.argsort(old_keys)
    idx = np.searchsorted(old_keys[order], keys)
    idx = np.minimum(idx, len(order) - 1)
    found = old_keys[order][idx] == keys
    out[found] = old_impulses[order[idx[found]]]
    return out


def narrow_phase(model: Model, state: State) -> Contacts:
    """Contacts of all candidates at the configuration ``state.q`` (impulses from the memory)."""
    centres = np.ascontiguousarray(model.rigid_view(state.q)[:, :2])
    dof0 = model.layout.rigid_dof0()
    parts = []
    pairs = state.pairs["disk_disk"]
    c = Contacts.empty(len(pairs))
    disk_disk_rows(pairs, centres, model.radii, dof0, c.dof, c.hn, c.ht, c.gap, c.normal, c.point, c.branch)
    c.pairs[:] = pairs
    c.body_i[:] = model.rigid_ids[pairs[:, 0]]
    c.body_j[:] = model.rigid_ids[pairs[:, 1]]
    c.mu[:] = model.friction[model.rigid_material[pairs[:, 0]], model.rigid_material[pairs[:, 1]]]
    c.impulse[:] = state.impulses["disk_disk"]
    parts.append(c)

    pairs = state.pairs["disk_wall"]
    c = Contacts.empty(len(pairs))
    disk_wall_rows(pairs, centres, model.radii, dof0, np.ascontiguousarray(model.bounds(state.q)),
                   model.layout.wall_dof0, WALL_NORMALS, WALL_AXES,
                   c.dof, c.hn, c.ht, c.gap, c.normal, c.point, c.branch)
    c.pairs[:] = pairs
    c.body_i[:] = model.rigid_ids[pairs[:, 0]]
    c.body_j[:] = -1 - pairs[:, 1]
    c.impulse[:] = state.impulses["disk_wall"]
    parts.append(c)
    return Contacts.concatenate(parts)


def store_impulses(state: State, contacts: Contacts) -> None:
    """Write the solved impulses back into the per-family memory (same order as narrow_phase)."""
    k = 0
    for fam in FAMILIES:
        m = len(state.pairs[fam])
        state.impulses[fam] = contacts.impulse[k:k + m].copy()
        k += m
