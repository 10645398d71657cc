"""Wall damping against the breathing mode (walls.damping_ratio, compute.bodies.walls).

The secant bulk modulus is checked on a pressure-area law whose modulus is known. The damping is
checked on a soft disk pressed by four walls with a time step small enough that it rings
(backward Euler damps little at h = 0.1): the disk has the same mode as a packing, the walls
moving in together against its bulk stiffness. Critical damping is the least that leaves no
overshoot after a step load, so the estimate of the mode's mass and stiffness holds when the
disk still overshoots its next equilibrium at 0.7 of it and creeps in from below at all of it.
Statics has no damping: every damping ends every stage at the same packing fraction, within a
few times the stage-end test's tolerance.
"""

import csv

import numpy as np
import pytest

from compute.bodies.walls import MAX_EXPONENT, breathing_damping, secant_bulk_modulus, stage_bulk_modulus
from compute.run import run
from pre import single_particle

PRESSURES = [1e-3, 1e-2, 3e-2]


def test_secant_bulk_modulus_of_an_exponential_law():
    # A = A0 exp(-P / K): ln(A_a / A_b) = (P_b - P_a) / K exactly
    p = np.array([0.0, 0.01, 0.03])
    assert secant_bulk_modulus(p, 5.0 * np.exp(-p / 0.7)) == pytest.approx(0.7, rel=1e-12)
    assert secant_bulk_modulus(p[:1], np.ones(1)) == 0.0  # one state: no modulus
    assert secant_bulk_modulus(p[:2], np.array([1.0, 1.0])) == 0.0  # the box did not shrink
    # critical damping 2 √(k m) of the mode: k = 4K, m = m_w + M/6
    assert breathing_damping(1.0, 0.5, 6.0, 2.0) == pytest.approx(2 * np.sqrt(2.0 * 3.0))
    assert breathing_damping(0.0, 0.5, 6.0, 2.0) == 0.0


def _power_law_areas(p, k0: float, alpha: float) -> np.ndarray:
    """Box areas under pressures ``p`` of a packing whose tangent modulus is K = k0 P^alpha
    (d ln A = -dP / K, integrated exactly)."""
    if alpha == 1.0:
        return np.exp(-np.log(p) / k0)
    return np.exp(-p ** (1.0 - alpha) / (k0 * (1.0 - alpha)))


@pytest.mark.parametrize("alpha", [0.0, 0.5, 1.0, 1.5, 2.0])
def test_stage_bulk_modulus_is_the_tangent_of_a_power_law(alpha):
    """Log-spaced pressures (the loading programs'), K = 3 P^alpha: the estimate at the next
    pressure is the exact tangent modulus there within the secant-against-tangent factor
    c(r, α) / r^(α/2) ≤ 1.06 (r = √10), while the last secant alone is below it by r^(1.5 α).
    (At α = 0 the estimate is the exact modulus, up to round-off in either direction.)"""
    p = 1e-3 * np.sqrt(10.0) ** np.arange(5)
    nxt = p[-1] * np.sqrt(10.0)
    exact = 3.0 * nxt ** alpha
    estimate = stage_bulk_modulus(p, _power_law_areas(p, 3.0, alpha), nxt)
    assert exact * (1.0 - 1e-12) <= estimate <= 1.06 * exact
    assert secant_bulk_modulus(p, _power_law_areas(p, 3.0, alpha)) < 1.06 * exact / np.sqrt(10.0) ** (1.5 * alpha)


def test_stage_bulk_modulus_guards():
    p = np.sqrt(10.0) ** np.arange(4)
    steep = _power_law_areas(p, 3.0, 3.0)  # steeper than MAX_EXPONENT: extrapolated as P^MAX_EXPONENT
    k_b = secant_bulk_modulus(p, steep)
    expected = k_b * (10 * p[-1] / np.sqrt(p[-1] * p[-2])) ** MAX_EXPONENT
    assert stage_bulk_modulus(p, steep, 10 * p[-1]) == pytest.approx(expected, rel=1e-12)
    # secants 2 then 1 (softening): not extrapolated downwards, the last secant
    q = np.array([1.0, 2.0, 4.0])
    a = np.exp(-np.cumsum([0.0, (2.0 - 1.0) / 2.0, (4.0 - 2.0) / 1.0]))
    assert stage_bulk_modulus(q, a, 8.0) == pytest.approx(1.0, rel=1e-12)
    # from P = 0 (the initial box) there is one interval of positive pressures: the secant
    q = np.array([0.0, 1e-3, 1e-2])
    a = np.array([2.0, 1.9, 1.8])
    assert stage_bulk_modulus(q, a, 0.1) == secant_bulk_modulus(q, a)


def _stages(folder, ratio: float):
    scene = folder / "scene"
    single_particle.write(scene, element="T3", elements=40, pressures=PRESSURES, time_step=0.1, check_every=20)
    toml = scene / "scene.toml"
    text = toml.read_text()
    assert "damping_ratio = 0.0" in text and "damping_inertial_number = 0.0" in text
    # a light damping of the inertial-number kind, for the first stage, which has no secant
    toml.write_text(text.replace("damping_ratio = 0.0", f"damping_ratio = {ratio!r}")
                    .replace("damping_inertial_number = 0.0", "damping_inertial_number = 0.5"))
    run(scene, folder / "out", log=lambda m: None)
    rows = list(csv.DictReader(open(folder / "out" / "history.csv")))
    stage = np.array([int(r["stage"]) for r in rows])
    phi = np.array([float(r["phi"]) for r in rows])
    later = (1, 2)  # the stages damped from the disk's own secant modulus
    return (np.array([phi[stage == s][-1] for s in range(len(PRESSURES))]),
            np.array([np.max(phi[stage == s]) - phi[stage == s][-1] for s in later]),
            np.array([np.count_nonzero(stage == s) for s in later]))


def test_the_critical_damping_is_where_the_overshoot_ends(tmp_path):
    ends, overshoot, steps = zip(*(_stages(tmp_path / str(r), r) for r in (0.0, 0.7, 1.0)))
    assert np.all(overshoot[0] > 1e-3)  # lightly damped, the disk rings past its equilibrium
    assert np.all(overshoot[1] > 1e-5)
    assert np.all(overshoot[2] == 0.0)  # it creeps in from below
    assert np.all(steps[2] < 0.7 * steps[0])  # and ends its stages sooner
    # The stage-end test bounds φ's change over a window (1e-5, relative), not its distance to
    # the equilibrium: an approach from one side ends up to a few windows' change short of it.
    for other in ends[1:]:
        np.testing.assert_allclose(other, ends[0], rtol=3e-5, atol=0)
