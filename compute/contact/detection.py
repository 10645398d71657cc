"""Detection for every contact family: one Verlet skin, one warm-start memory, one narrow phase.

The candidate lists and the impulses of the last step live in ``state.pairs`` /
``state.impulses`` per family (:mod:`compute.contact.families`, in registry order). The lists are
rebuilt only when a rigid centre or a soft boundary node has moved more than half the skin
since the last detection (or a wall and a body together more than the skin); impulses of
candidates that survive a rebuild are kept (warm start), matched on the first two columns.
"""

from __future__ import annotations

import numpy as np

from compute.contact.families import Broad
from compute.contact.rows import ContactRows
from compute.state import State


def skin_distance(model) -> float:
    return model.skin * model.diameter


def needs_detection(model, state: State) -> bool:
    """True when the lists are missing or something moved past the Verlet criterion."""
    if state.q_detect is None or any(f.name not in state.pairs for f in model.families):
        return True
    moved = model.tracked_points(state.q) - model.tracked_points(state.q_detect)
    dmax = float(np.sqrt(np.max(np.sum(moved**2, axis=1)))) if len(moved) else 0.0
    wmax = float(np.max(np.abs(model.walls.bounds(state.q) - model.walls.bounds(state.q_detect))))
    skin = skin_distance(model)
    return 2.0 * dmax > skin or dmax + wmax > skin


def detect(model, state: State) -> None:
    """Rebuild every candidate list in place, carrying the impulses of surviving candidates."""
    skin = skin_distance(model)
    broad = Broad(model, state.q, skin)
    for fam in model.families:
        pairs = fam.candidates(model, state.q, broad, skin)
        state.impulses[fam.name] = carry(state.pairs.get(fam.name), state.impulses.get(fam.name), pairs)
        state.pairs[fam.name] = pairs
    state.q_detect = state.q.copy()


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


def narrow_phase(model, state: State, branches: bool = True) -> ContactRows:
    """ContactRows of all families at ``state.q`` with the impulses of the memory.

    ``branches``: fill the branch vectors (from the body centres: soft centroids), which frames
    need and a step does not.
    Row entries that carry no impulse (a zero normal row, and a zero tangential row or no
    friction) are dropped, so that the dense compliance blocks cover only the dofs that matter.
    """
    q = state.q
    centres = model.centres(q) if branches and model.soft else None
    parts = [fam.rows(model, q, state.pairs[fam.name], centres) for fam in model.families]
    out = ContactRows.concatenate(parts) if parts else ContactRows.empty(0)
    idle = (out.hn == 0.0) & ((out.mu == 0.0)[:, None] | (out.ht == 0.0))
    out.dof[idle] = -1
    if len(out):
        out.impulse[:] = np.concatenate([state.impulses[f.name] for f in model.families])
    return out


def family_slices(model, state: State) -> dict[str, slice]:
    """{family name: its rows} in the ContactRows of :func:`narrow_phase` at ``state``."""
    out, k = {}, 0
    for fam in model.families:
        m = len(state.pairs[fam.name])
        out[fam.name] = slice(k, k + m)
        k += m
    return out


def store_impulses(model, state: State, impulse: np.ndarray) -> None:
    """Write solved impulses (nc, 2) back to the memory, in the order of :func:`narrow_phase`."""
    for name, rows in family_slices(model, state).items():
        state.impulses[name] = impulse[rows].copy()
