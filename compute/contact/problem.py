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

from compute.contact.compliance import Compliance, block_delassus, delassus_blocks
from compute.contact.rows import ContactRows, generalised_impulse
from compute.contact.residual import natural_map_error, velocity_error


def gap_term(gap: np.ndarray, un_minus: np.ndarray, h: float, theta: float) -> np.ndarray:
    """g̃ / (h θ) (nc,) of gaps ``gap`` and normal velocities u_n⁻ ``un_minus`` (nc,) at the step's
    start: g̃ = g + h (1 − θ) u_n⁻, the end-of-step gap predicted without the step's own motion."""
    return (gap + h * (1.0 - theta) * un_minus) / (h * theta)


@dataclass
class ContactProblem:
    """``dof``, ``hn``, ``ht`` (nc, MAX_DOFS) sparse rows of H over the packed dofs of
    ``compliance`` (:mod:`compute.contact.compliance`); ``W`` (nc, 2, 2); ``v_free`` (n_dofs,)
    over all dofs (a caller may update it in place between solves); ``gap_term`` (nc,); ``mu``
    (nc,); ``impulse`` (nc, 2) the warm start, overwritten with the solution by a solver;
    ``h_theta`` h θ of the step."""

    dof: np.ndarray
    hn: np.ndarray
    ht: np.ndarray
    W: np.ndarray
    compliance: Compliance
    v_free: np.ndarray
    gap_term: np.ndarray
    mu: np.ndarray
    impulse: np.ndarray
    h_theta: float = 1.0  # h θ: what turns the normal velocity error into an overlap

    @classmethod
    def build(cls, contacts: ContactRows, compliance: Compliance, v_free: np.ndarray, v_minus: np.ndarray,
              h: float, theta: float) -> "ContactProblem":
        """The problem of ``contacts`` (rows at q_n, impulses = warm start) for velocities v⁻ (n_dofs,)."""
        un_minus = np.sum(contacts.hn * np.where(contacts.dof >= 0, v_minus[contacts.dof], 0.0), axis=1)
        return cls.of_rows(contacts.dof, contacts.hn, contacts.ht, compliance, v_free,
                           gap_term(contacts.gap, un_minus, h, theta), contacts.mu, contacts.impulse, h * theta)

    @classmethod
    def of_rows(cls, dof, hn, ht, compliance: Compliance, v_free, gap_term, mu, impulse,
                h_theta: float = 1.0) -> "ContactProblem":
        """The problem of rows ``dof`` (over global dofs), ``hn``, ``ht`` (nc, m) with the other
        fields as in the class docstring; W computed."""
        packed = compliance.packed_rows(dof)
        W = np.empty((len(gap_term), 2, 2))
        delassus_blocks(packed, hn, ht, *compliance.arrays(), W)
        return cls(packed, hn, ht, W, compliance, v_free, gap_term, mu, impulse, h_theta)

    def __len__(self) -> int:
        return len(self.gap_term)

    def set_rows(self, rows: np.ndarray, hn: np.ndarray, ht: np.ndarray, gap_term: np.ndarray) -> None:
        """Replace the rows ``rows`` (k,) by ``hn``, ``ht`` (k, MAX_DOFS) over the same dofs and
        their gap terms (k,); their Delassus blocks are recomputed
        (compute.contact.end_of_step)."""
        self.hn[rows], self.ht[rows], self.gap_term[rows] = hn, ht, gap_term
        W = np.empty((len(rows), 2, 2))
        delassus_blocks(self.dof[rows], hn, ht, *self.compliance.arrays(), W)
        self.W[rows] = W

    def restricted(self, rows: np.ndarray) -> "ContactProblem":
        """The problem of the contacts ``rows`` (k,) alone, their impulses copied; it shares
        ``compliance`` and ``v_free`` (:mod:`compute.solvers.screened`)."""
        return ContactProblem(self.dof[rows], self.hn[rows], self.ht[rows], self.W[rows], self.compliance,
                              self.v_free, self.gap_term[rows], self.mu[rows], self.impulse[rows], self.h_theta)

    def free_velocity(self) -> np.ndarray:
        """v_free on the packed dofs (n,): a solver's starting velocities."""
        return self.v_free[self.compliance.order]

    def velocities(self, v_packed: np.ndarray) -> np.ndarray:
        """All velocities (n_dofs,): ``v_packed`` (n,) on the packed dofs, v_free elsewhere."""
        v = self.v_free.copy()
        v[self.compliance.order] = v_packed
        return v

    def error(self, v: np.ndarray) -> float:
        """Natural-map error (:mod:`compute.contact.residual`) of the impulses with velocities v (n_dofs,)."""
        return natural_map_error(self.dof, self.hn, self.ht, self.W, self.gap_term, self.mu, self.impulse,
                                 v[self.compliance.order])

    def velocity_error(self, v: np.ndarray) -> tuple[float, float]:
        """(packing, worst contact) natural-map error in velocity units
        (:func:`compute.contact.residual.velocity_error`) with velocities v (n_dofs,)."""
        o = self.compliance.order
        return velocity_error(self.dof, self.hn, self.ht, self.W, self.gap_term, self.mu, self.impulse, v[o],
                              self.v_free[o])

    def normal_velocity(self, v: np.ndarray) -> np.ndarray:
        """ũ_n = H_nᵀ v + gap_term (nc,) for velocities v (n_dofs,): the normal velocity whose
        sign Signorini's condition reads."""
        vp = v[self.compliance.order]
        return self.gap_term + np.sum(self.hn * np.where(self.dof >= 0, vp[self.dof], 0.0), axis=1)

    def normal_delassus(self, rows: np.ndarray) -> np.ndarray:
        """Dense normal Delassus block (k, k) H_nᵀ M̂⁻¹ H_n of the contacts ``rows`` (k,)."""
        rows = np.asarray(rows, np.int64)
        k = rows.size
        wb, _ = block_delassus(rows, np.array([0, k], np.int64), self.dof, self.hn, self.ht,
                               *self.compliance.arrays())
        return wb.reshape(2 * k, 2 * k)[0::2, 0::2]

    def generalised_impulse(self, n_dofs: int) -> np.ndarray:
        """H r (n_dofs,) of the current impulses."""
        hr = np.zeros(n_dofs)
        hr[self.compliance.order] = generalised_impulse(self.dof, self.hn, self.ht, self.impulse, len(self.compliance))
        return hr
