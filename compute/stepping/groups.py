"""The body groups as the stepper sees them: through the protocols of compute.bodies.protocols
only, so that stepping/ never asks what kind of body it holds.

:class:`StepGroups` holds the model's groups for a run (what outlives a step: kept
factorisations and their counts); :meth:`StepGroups.begin_step` returns a :class:`GroupStep`,
the groups with the records of one step attempt, which the Newton loops
(compute.stepping.newton, compute.stepping.active_set) call.
"""

from __future__ import annotations

import numpy as np

from compute.bodies.step_records import LinearStep


class StepGroups:
    """The ``groups`` of a model (in dof order) over ``n_dofs`` dofs, split into linear groups
    (``nonlinear`` False) and nonlinear ones."""

    def __init__(self, groups, n_dofs: int):
        self.groups = list(groups)
        self.nonlinear = [g for g in self.groups if g.nonlinear]
        self.n_dofs = n_dofs

    @property
    def iterates(self) -> bool:
        """True when some nonempty group needs Newton iterations within a step."""
        return any(len(g) for g in self.nonlinear)

    @property
    def holds_rotation(self) -> bool:
        """True when some nonlinear group holds its bodies' rotation (SoftBodies.hold_torques)."""
        return any(g.hold_rotation for g in self.nonlinear)

    def begin_step(self, q: np.ndarray, v: np.ndarray, h: float, theta: float, load) -> "GroupStep":
        """Every group's record of a step of size h from (q, v) under ``load``."""
        records = [g.begin_step(q, v, h, theta, load) for g in self.groups]
        return GroupStep(self.n_dofs, h, theta, [r for g, r in zip(self.groups, records) if not g.nonlinear],
                         [(g, r) for g, r in zip(self.groups, records) if g.nonlinear])

    def factorisation_counts(self) -> tuple[int, int]:
        """(numeric factorisations, stabilised ones) of all nonlinear groups so far."""
        counts = [g.factorisation_counts() for g in self.nonlinear]
        return sum(c[0] for c in counts), sum(c[1] for c in counts)

    def forget_factorisations(self) -> None:
        """The next step starts without reused factorisations (Stepper.restart_point)."""
        for g in self.nonlinear:
            g.forget_factorisations()


class GroupStep:
    """The groups during one step attempt of size ``h``: ``linear`` the LinearStep records of the
    linear groups, ``iterated`` (group, SoftStep) of the nonlinear ones."""

    def __init__(self, n_dofs: int, h: float, theta: float, linear: list[LinearStep], iterated: list[tuple]):
        self.n_dofs, self.h, self.theta = n_dofs, h, theta
        self.linear, self.iterated = linear, iterated

    @property
    def iterates(self) -> bool:
        """True when some nonempty group needs Newton iterations (StepGroups.iterates)."""
        return any(len(g) for g, _ in self.iterated)

    def diagonals(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """1x1 compliance blocks of the linear groups: [(dofs (k,), 1 / m̂ (k,))]."""
        return [(r.dofs, r.inverse) for r in self.linear]

    def initial_velocity(self, v_minus: np.ndarray) -> np.ndarray:
        """The first iterate (n_dofs,): the linear groups' free velocity, v⁻ on the others."""
        v = np.zeros(self.n_dofs)
        for r in self.linear:
            v[r.dofs] = r.v_free
        for g, _ in self.iterated:
            v[g.dofs] = v_minus[g.dofs]
        return v

    def free_velocity(self, v: np.ndarray, out: np.ndarray, exact: bool = False) -> None:
        """Every group's free velocity at the iterate v, written to ``out``; ``exact``: the
        nonlinear groups take a Newton iteration (SoftBodies.refresh)."""
        for r in self.linear:
            out[r.dofs] = r.v_free
        for g, st in self.iterated:
            if exact:
                g.refresh(st)
            g.free_velocity(st, v, out)

    def contact_dofs(self, contacts) -> list[tuple]:
        """[(group, its SoftStep, sorted unique global dofs (m,) of the group that contact rows
        touch)] of the nonlinear groups."""
        d = np.unique(contacts.dof)
        return [(g, st, d[(d >= g.dofs.start) & (d < g.dofs.stop)]) for g, st in self.iterated]

    def factorisation_stamp(self) -> list[int]:
        """Changes whenever some body refactorises (compliance blocks to redo)."""
        return [g.factorisation_stamp() for g, _ in self.iterated]

    def compliance_times(self, hr: np.ndarray) -> np.ndarray:
        """M̂⁻¹ hr (n_dofs,) for a generalised impulse hr (n_dofs,): 1x1 blocks of the linear
        groups, batched solves of the nonlinear ones."""
        y = np.zeros_like(hr)
        for r in self.linear:
            y[r.dofs] = r.inverse * hr[r.dofs]
        for g, _ in self.iterated:
            y[g.dofs] = g.compliance_times(hr).ravel()
        return y

    def recover(self, v_new: np.ndarray, v_free: np.ndarray, y: np.ndarray) -> None:
        """v_b = v_free,b + (M̂⁻¹ H r)_b on all dofs of the nonlinear groups (interior recovery)."""
        for g, _ in self.iterated:
            v_new[g.dofs] = v_free[g.dofs] + y[g.dofs]

    def settle(self, v_old: np.ndarray, v_new: np.ndarray, tol: float) -> None:
        for g, st in self.iterated:
            g.settle(st, v_old, v_new, tol)

    def contraction_was_slow(self) -> None:
        for g, st in self.iterated:
            g.contraction_was_slow(st)

    def corrections(self, v_old: np.ndarray, v_new: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Body ids (nd,) and position corrections (nd,) of every body of the nonlinear groups."""
        ids = np.concatenate([np.zeros(0, np.int64)] + [g.ids for g, _ in self.iterated])
        return ids, np.concatenate([np.zeros(0)] + [g.corrections(st, v_old, v_new) for g, st in self.iterated])

    def area_violation(self, v: np.ndarray, lo: float, hi: float):
        """None if every element keeps J / J_n within [lo, hi] with velocities v (n_dofs,); else
        (body id, elements, smallest ratio) of the first body that does not."""
        return next((b for b in (g.area_change(st, v, lo, hi) for g, st in self.iterated) if b is not None), None)

    def use_indefinite(self, on: bool) -> None:
        for g, _ in self.iterated:
            g.use_indefinite(on)

    def expected_negative(self) -> int:
        return sum(g.expected_negative() for g, _ in self.iterated)

    def hold_torque(self, v: np.ndarray, hr: np.ndarray) -> float:
        """The largest relative torque of the rotation holds over the step (SoftBodies.hold_torques)."""
        return max((float(g.hold_torques(st, v, hr).max(initial=0.0)) for g, st in self.iterated if g.hold_rotation),
                   default=0.0)
