r"""Segment–disk rows linearised at the end of the step (backward Euler contact geometry).

A contact row predicts the end-of-step gap from the rows of H at q_n:
g(q⁺) ≈ g(q_n) + H_nᵀ Δq, Δq = q⁺ − q_n = h((1 − θ) v⁻ + θ v⁺), and its impulse acts along the
normal at q_n. That is harmless where the normal depends on the relative position of the two
bodies alone (disk–disk, node–disk, walls). The normal of a rigid disk d against a soft boundary
segment [x_g, x_b] is the segment's own outward normal n; its gap

    g = (x_d − x_g) · n − r_d

is not convex in the positions. A segment that turns by an angle a = ω h within the step
leaves two errors of the rows at q_n:

- the gap closes by about (r_d + g) a² / 2 − a Δ·t more than predicted (Δ the disk's motion
  relative to x_g, t the segment's tangent), so the disk ends the step inside the soft body
  and the next step pushes it out;
- the impulse acts along the normal of the step's start, which lags the segment's by a. On a
  turning polygon that lag is a tangential force along the turning, a torque ∝ r_n a R: a
  frictionless soft disk pressed by rigid disks is driven to spin, the energy
  kinetic + strain + P × box area rises where it can only fall, and a small frictionless
  mixture may never come to rest (benchmarks/results/end_of_step_rows.md).

Rows linearised again at the end-of-step positions q¹⁺ of the step's first Newton iterate
(compute.stepping.newton, ``RELINEARISED_AT``) remove most of both: their normal, contact point
and weights are those of q¹⁺, and their gap term is the gap at q¹⁺ carried back,
g(q¹⁺) − H_n(q¹⁺)ᵀ (q¹⁺ − q_n), so that the row's prediction is exact at q¹⁺ and wrong only by
second order in q⁺ − q¹⁺, the first iterate's error, instead of in the whole step's turn. As
backward Euler treats every other force, the contact force acts along the end-of-step normal
(to that order) and no longer drives the polygon's turning. Why once and not at every iterate,
which would make Signorini hold on the exact gap at the converged step: the turning of the
contact forces with their segments (a geometric stiffness of the contacts) is not in the
Newton tangent, and rows renewed at every iterate make the fixed point converge slowly at high
pressure (benchmarks/results/end_of_step_rows.md). Only rows whose disk projects inside its
segment at q_n are relinearised (both segment nodes in the row); the others are node–disk
rows, convex. And only frictionless ones: the lag's tangential force, a r_n, lies within a
frictional contact's cone (a ≪ μ), which holds it as it holds any tangential load, and the
frictional mixtures' energy falls with the rows of q_n (benchmarks/results/end_of_step_rows.md),
while making the rows again costs a re-solve of the contact problem within the step. And only
in a step taken at the full time step h, not in the sub-steps of a cut one (compute.stepping.control):
a sub-step of h / 2^k turns its segments by about a 2^k-th of the step's turn, so the lag and the
torque it leaves are as much smaller, while every sub-step would pay the re-solve; high-pressure
stages take most of their steps in sub-steps, where the re-solve doubled the contact iterations
(benchmarks/results/end_of_step_rows.md, "Full steps only").
"""

from __future__ import annotations

import numba
import numpy as np

from compute.contact import detection
from compute.contact.problem import gap_term
from compute.contact.rows import ContactRows
from compute.contact.soft_rows import segment_disk_rows


class EndOfStepSegmentRows:
    """The segment–disk rows ``rows`` (k,) of one step's ContactRows, with their pairs ``pairs``
    (k, 2) (segment start node, local rigid disk); ``q``, ``v_minus`` (n_dofs,) the positions and
    velocities at the step's start, ``h``, ``theta`` the (sub-)step."""

    def __init__(self, model, q: np.ndarray, v_minus: np.ndarray, h: float, theta: float, rows: np.ndarray,
                 pairs: np.ndarray):
        self.model, self.q, self.v_minus, self.h, self.theta = model, q, v_minus, h, theta
        self.q_explicit = q + h * (1.0 - theta) * v_minus
        self.rows, self.pairs = rows, np.ascontiguousarray(pairs)

    @classmethod
    def of_step(cls, model, state, contacts: ContactRows, h: float, theta: float) -> "EndOfStepSegmentRows | None":
        """The frictionless rows of ``contacts`` (made at ``state``'s positions) of the
        segment–disk family that hold both segment nodes and both translations of the disk (a row
        drops the entries that are exactly 0 at q_n, compute.contact.detection.narrow_phase, and
        its dofs stay those of q_n); None when there are none."""
        family = detection.family_slices(model, state).get("segment_disk")
        if family is None:
            return None
        dof, mu = contacts.dof[family], contacts.mu[family]
        inside = np.flatnonzero(np.all(dof[:, :6] >= 0, axis=1) & (mu == 0.0))  # nodes g, b and the disk
        if not inside.size:
            return None
        return cls(model, state.q, state.v, h, theta, family.start + inside, state.pairs["segment_disk"][inside])

    def relinearise(self, contacts: ContactRows, problem, v: np.ndarray) -> None:
        """Rewrite the rows in ``contacts`` (hn, ht, normal, point, gap) and in ``problem`` (a
        ContactProblem of ``contacts``, or None) at the end-of-step positions
        q⁺ = q + h((1 − θ) v⁻ + θ v) of velocities ``v`` (n_dofs,)."""
        m, rows = self.model, self.rows
        q = self.q_explicit + self.h * self.theta * v
        r = m.rigid
        at = ContactRows.empty(len(rows))
        segment_disk_rows(self.pairs, m.soft_nodes(q), m.node_dof0, m.loop_neighbours,
                          np.ascontiguousarray(r.centres(q)), r.radii, r.dof_of(), at.dof, at.hn, at.ht, at.gap,
                          at.normal, at.point)
        un_minus = np.empty(len(rows))
        _carried_back(rows, contacts.dof, at.hn, at.ht, at.gap, q - self.q, self.v_minus, un_minus)
        contacts.hn[rows], contacts.ht[rows], contacts.gap[rows] = at.hn, at.ht, at.gap
        contacts.normal[rows], contacts.point[rows] = at.normal, at.point
        if problem is not None:
            problem.set_rows(rows, at.hn, at.ht, gap_term(at.gap, un_minus, self.h, self.theta))


@numba.njit(cache=True)
def _carried_back(rows, dof, hn, ht, gap, dq, v_minus, un_minus):
    """In place: the entries of hn, ht (k, MAX_DOFS) that the step's rows ``dof[rows]`` dropped
    set to 0, ``gap`` (k,) from the gap at q⁺ to g(q⁺) − hnᵀ (q⁺ − q_n) (dq = q⁺ − q_n), and
    ``un_minus`` (k,) = hnᵀ v⁻."""
    for k in range(rows.shape[0]):
        moved = 0.0
        before = 0.0
        for j in range(dof.shape[1]):
            d = dof[rows[k], j]
            if d < 0:
                hn[k, j] = 0.0
                ht[k, j] = 0.0
            else:
                moved += hn[k, j] * dq[d]
                before += hn[k, j] * v_minus[d]
        gap[k] -= moved
        un_minus[k] = before
