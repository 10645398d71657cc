"""Mass scaling (solver.mass_scaling, compute.bodies.soft): the soft bodies' inertia is scaled
per pressure stage, and the equilibria the stages end on do not depend on it.

Statics has no mass: a disk pressed to equilibrium in each stage, once with its material's
inertia and once with 1.25, 12.5 and 37.5 times it, must end every stage at the same packing fraction
within the stage-end test's own tolerance; the path between (steps, kinetic energies) differs."""

import csv

import numpy as np
import pytest

from compute.bodies.soft import mass_scale
from compute.run import run
from pre import single_particle


def _stage_ends(folder, mass_scaling: float):
    scene = folder / "scene"
    single_particle.write(scene, element="T3", elements=40, pressures=[1e-3, 1e-2, 3e-2])
    toml = scene / "scene.toml"
    text = toml.read_text()
    assert "mass_scaling = 0.0" in text
    toml.write_text(text.replace("mass_scaling = 0.0", f"mass_scaling = {mass_scaling!r}"))
    run(scene, folder / "out", log=lambda m: None)
    rows = list(csv.DictReader(open(folder / "out" / "history.csv")))
    ends = {int(r["stage"]): float(r["phi"]) for r in rows}  # the last row of each stage
    return np.array([ends[s] for s in sorted(ends)]), len(rows)


def test_stage_ends_do_not_depend_on_the_inertia(tmp_path):
    plain, steps_plain = _stage_ends(tmp_path / "plain", 0.0)
    scaled, steps_scaled = _stage_ends(tmp_path / "scaled", 50.0)
    # c P h² / (ρ ⟨d⟩²) with h = 10, ρ = 1 and the disk's diameter 2
    assert [mass_scale(50.0, p, 10.0, 1.0, 2.0) for p in (1e-3, 1e-2, 3e-2)] == pytest.approx([1.25, 12.5, 37.5])
    assert steps_scaled != steps_plain  # the scaling acted on the path
    # within the stage-end test's phi_tolerance (1e-5, relative)
    np.testing.assert_allclose(scaled, plain, rtol=1e-5, atol=0)
