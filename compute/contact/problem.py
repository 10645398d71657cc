r"""The contact problem of one step (or one Newton iteration), as a contact solver receives it.

Unknowns: the contact impulses r (nc, 2) = (r_n, r_t) over the step. With the rows of H at q_n,
the compliance M̂⁻¹ restricted to the dofs contacts touch and the free velocity v_free:

    v = v_free + M̂⁻¹ H r,     u = Hᵀ v          (end-of-step velocities, local velocities)
    Signorini on g̃ + h θ u_n,  g̃ = g + h (1 - θ) u_n⁻        (predicted end-of-step gap)
    Coulomb on (r, u_t) with μ.

``gap_term`` = g̃ / (h θ), so that the normal condition reads on ũ_n = u_n + gap_term;
``W`` (nc, 2, 2) the local Delassus blocks H_cᵀ M̂⁻¹ H_c.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from compute.contact.compliance import Compliance, delassus_blocks
from compute.contact.rows import ContactRows, generalised_impulse


@dataclass
class ContactProblem:
    """``dof``, ``hn``, ``ht`` (nc, MAX_DOFS) sparse rows of H; ``W`` (nc, 2, 2); ``compliance``;
    ``v_free`` (n_dofs,); ``gap_term`` (nc,); ``mu`` (nc,); ``impulse`` (nc, 2) the warm start,
    overwritten with the solution by a solver."""

    dof: np.ndarray
    hn: np.ndarray
    ht: np.ndarray
    W: np.ndarray
    compliance: Compliance
    v_free: np.ndarray
    gap_term: np.ndarray
    mu: np.ndarray
    impulse: np.ndarray

    @classmethod
    def build(cls, contacts: ContactRows, compliance: Compliance, v_free: np.ndarray, v_minus: np.ndarray,
              h: float, theta: float) -> "ContactProblem":
        """The problem of ``contacts`` (rows at q_n, impulses = warm start) for velocities v⁻ (n_dofs,)."""
        un_minus = np.sum(contacts.hn * np.where(contacts.dof >= 0, v_minus[contacts.dof], 0.0), axis=1)
        gap_term = (contacts.gap + h * (1.0 - theta) * un_minus) / (h * theta)
        W = np.empty((len(contacts), 2, 2))
        delassus_blocks(contacts.dof, contacts.hn, contacts.ht, *compliance.arrays(), W)
        return cls(contacts.dof, contacts.hn, contacts.ht, W, compliance, v_free, gap_term, contacts.mu,
                   contacts.impulse)

    def __len__(self) -> int:
        return len(self.gap_term)

    def generalised_impulse(self, n_dofs: int) -> np.ndarray:
        """H r (n_dofs,) of the current impulses."""
        return generalised_impulse(self.dof, self.hn, self.ht, self.impulse, n_dofs)
