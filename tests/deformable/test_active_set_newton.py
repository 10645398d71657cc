"""The active-set Newton (compute.stepping.active_set) against the fixed-point Newton loop
(compute.stepping.newton) on the same held-rotation steps: the single-particle disk (T6 x 31)
pressed by its four walls through P/E = 1e-3 ... 0.1 (5 stages of 30 steps, h = 10).

The two solve the same step equations by different iterations (a semismooth Newton on the
KKT system with the exact, possibly indefinite M̂; a fixed point around a complete contact
solve with a positive definite M̂), so their end-of-step states must agree to within their
tolerances; the first converges quadratically once the active set holds, the second linearly."""

import numpy as np
import pytest

from compute.stepping import active_set, strategies
from pre.single_particle import write
from tests.deformable import scenes

PRESSURES = tuple(np.geomspace(1e-3, 0.1, 5))
STEPS = 30  # per pressure: near equilibrium at the end of each


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    return write(tmp_path_factory.mktemp("sp"), elements=31, pressures=PRESSURES)


def press(folder, active: bool):
    """Final state, stepper statistics and Newton iterations of every step, pressing the disk
    with the active-set Newton or (active False) the fixed-point loop."""
    model, stepper, state = scenes.load(folder)
    # one soft body, rotation held, frictionless walls: auto takes the active-set Newton
    assert stepper.strategy is strategies.STRATEGIES["active_set"]
    stepper.strategy = strategies.STRATEGIES["active_set" if active else "fixed_point"]
    iterations = []
    for p in PRESSURES:
        for _ in range(STEPS):
            state, rep = stepper.step(state, p)
            iterations.append(rep.newton_iterations)
    return state, stepper.stats, iterations


def test_active_set_and_fixed_point_reach_the_same_equilibria(folder):
    """The same end state: the disk has moved by about 0.1 R; what is left between the two runs
    (4e-6 measured) is the transient each leaves after 30 steps, which decays with more steps."""
    state_a, stats_a, its_a = press(folder, True)
    state_f, stats_f, its_f = press(folder, False)
    moved = np.abs(state_f.q - scenes.load(folder)[2].q).max()
    assert moved > 0.05
    np.testing.assert_allclose(state_a.q, state_f.q, atol=1e-4 * moved)
    assert sum(its_a) < sum(its_f)
    # quadratic convergence: near equilibrium, the last steps at each pressure take 2 iterations
    for k in range(len(PRESSURES)):
        assert max(its_a[(k + 1) * STEPS - 5:(k + 1) * STEPS]) <= 2


def test_a_failing_active_set_newton_hands_the_step_to_the_fixed_point_loop(folder, monkeypatch):
    """With one iteration allowed the active-set Newton fails every attempt that does not end at
    once; the fixed-point loop then takes those steps: the run is the fixed-point run (to within
    the Newton tolerance of the few steps the active-set Newton took in one iteration)."""
    monkeypatch.setattr(active_set, "ITERATIONS", 1)
    state_a, stats_a, _ = press(folder, True)
    state_f, _, _ = press(folder, False)
    assert stats_a["fallbacks"] > len(PRESSURES) * STEPS // 2
    np.testing.assert_allclose(state_a.q, state_f.q, atol=1e-7)
