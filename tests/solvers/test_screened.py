"""Contact solves on the contacts that can close (compute.solvers.screened) against the Lemke
oracle on the whole problem: the contacts left out must change no solution, with or without
friction, and a contact pushed shut by the others' impulses must be found and added."""

from dataclasses import dataclass, field

import numpy as np
import pytest

from compute.solvers.mprgp import MPRGP
from compute.solvers.nlgs import NLGS
from compute.solvers.screened import Screened
from tests.solvers.lemke import solve_contact
from tests.solvers.problems import dense_form, random_problem


@dataclass
class Recording:
    """A solver that records the number of contacts of each problem it is given."""

    inner: object
    sizes: list = field(default_factory=list)

    @property
    def tolerance(self):
        return self.inner.tolerance

    @property
    def measure(self):
        return self.inner.measure

    def solve(self, problem):
        self.sizes.append(len(problem))
        return self.inner.solve(problem)


@pytest.mark.parametrize("kind", ("rigid", "soft", "mixed"))
@pytest.mark.parametrize("friction", (0.0, 0.5))
def test_screened_solve_is_the_whole_problems_solution(kind, friction):
    rounds, first_rows = [], []
    for seed in range(20):
        p = random_problem(np.random.default_rng(700 + seed), kind, 12, friction=max(friction, 1e-9))
        if friction == 0.0:
            p.mu[:] = 0.0
        _, _, W, b = dense_form(p)
        expected = solve_contact(W, b, p.mu)
        inner = Recording(MPRGP(1e-12, 5000) if friction == 0.0 else NLGS(1e-12, 200_000))
        report = Screened(inner, 0.05).solve(p)
        u, u_ref = W @ p.impulse.ravel() + b, W @ expected.ravel() + b
        np.testing.assert_allclose(u, u_ref, rtol=0, atol=1e-7 * max(np.abs(u_ref).max(), 1.0))
        assert report.residual <= 1e-12
        rounds.append(len(inner.sizes))
        first_rows.append(inner.sizes[0])
    assert min(first_rows) < 12  # contacts were left out
    assert max(rounds) > 1  # and some that closed were found and added


def test_screened_solve_keeps_warm_started_contacts():
    """A contact holding an impulse is solved from the first round, whatever its free approach."""
    p = random_problem(np.random.default_rng(5), "rigid", 12)
    p.mu[:] = 0.0
    u = p.normal_velocity(p.v_free)
    far = int(np.argmax(u))  # the contact opening fastest: left out on its free motion alone
    p.impulse[far, 0] = 1.0
    inner = Recording(MPRGP(1e-12, 5000))
    Screened(inner, 0.05).solve(p)
    assert inner.sizes[0] == np.count_nonzero(u < 0.05 * -u.min()) + 1
