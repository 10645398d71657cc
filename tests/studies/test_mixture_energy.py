"""A frictionless mixture of rigid and soft disks under constant wall pressure can only lose
energy: contacts without restitution, backward Euler on the soft bodies and damped walls
dissipate, and nothing supplies work while P is constant. The energy is the packing's enthalpy

    E = kinetic + strain energy of the soft bodies + P × box area,

measured after every step of the study's default 30-disk κ = 0.5, μ = 0 run (prepared by the
study's pre.py) over its first two stages, P/E = 1e-3 and 3.2e-3, started from the shared packing
itself (``--relax none``), so that the first stage is the frictionless flow to a denser packing. With the
segment–disk rows linearised at the step's start only, the soft polygons were driven to spin: E rose at about half
the steps of the second stage and it never came to rest (compute.contact.end_of_step).
"""

import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]


def test_a_frictionless_mixture_loses_energy_and_comes_to_rest(tmp_path):
    from compute.run import Run

    pre = subprocess.run([sys.executable, "-m", "studies.mixture_compaction.pre", "--workdir", str(tmp_path),
                          "--n", "30", "--kappa", "0.5", "--mu", "0", "--jamming-mu", "0.2", "--relax", "none", "--pressures", "0.001", "0.0031622776601683794"],
                         cwd=ROOT, capture_output=True, text=True)
    assert pre.returncode == 0, pre.stderr
    run = Run(tmp_path / "runs" / "k0.5_mu0_s1" / "scene", tmp_path / "out", log=lambda msg: None)
    m, take = run.model, run.stepper.step
    energy: dict[int, list[float]] = {}

    def step(state, pressure, wall_speed=0.0):
        new, rep = take(state, pressure, wall_speed)
        b = m.bounds(new.q)
        strain = sum(float(np.sum(g.batch.strain_energy(g.nodes(new.q)))) for g in m.soft)
        if pressure == run.scene.loading.pressures[state.stage]:  # a stage's load, once fully applied
            energy.setdefault(state.stage, []).append(m.kinetic_energy(new.v) + strain
                                                      + pressure * (b[1] - b[0]) * (b[3] - b[2]))
        return new, rep

    run.stepper.step = step
    run.execute()
    assert (tmp_path / "out" / "COMPLETE").exists()  # both stages came to rest within their step budget
    for stage in (0, 1):
        e = np.array(energy[stage])
        rises = np.diff(e) > 0.0
        assert rises.mean() < 0.05, (stage, rises.mean())
        thirds = np.array_split(e, 3)
        assert all(part[-1] < part[0] for part in thirds), (stage, [part[-1] - part[0] for part in thirds])
