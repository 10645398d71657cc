"""A stage that makes no progress (compute.stall) ends the run INCOMPLETE within the stall window,
with a diagnosis naming the stage, the contact error and what to change, instead of running to
max_steps_per_stage."""

import numpy as np

from compute.run import run
from pre.packing import polydisperse_radii, random_loose_packing
from pre.scene import default_parameters, write_scene

STALL = 300
MAX_STEPS = 20000


def test_a_rigid_scene_whose_contact_solves_cannot_converge_stops_stalled(tmp_path):
    """12 rigid disks with 5 contact sweeps per solve: the contact error sits near 1e-2 and the
    packing stops moving (the issue's scene went 28 000 steps of its stage 0 this way)."""
    rng = np.random.default_rng(1)
    radii = polydisperse_radii(12, rng=rng)
    centres, box = random_loose_packing(radii, 0.5, rng)
    p = default_parameters(box, 0.3, 1.0, [1.0, 2.0])
    p["solver"]["nlgs_max_sweeps"] = 5
    p["loading"].update(max_steps_per_stage=MAX_STEPS, stall_steps=STALL)
    scene = write_scene(tmp_path / "scene", p, centres, radii, ["rigid"] * 12)
    state = run(scene, tmp_path / "out", log=lambda m: None)

    reasons = (tmp_path / "out" / "INCOMPLETE").read_text()
    assert "stage 0 (P = 1) stalled" in reasons and "solver.nlgs_max_sweeps = 5: raise it" in reasons, reasons
    assert state.stage == 0 and state.stage_steps < MAX_STEPS  # ended early, the second stage never run
    h = np.genfromtxt(tmp_path / "out" / "history.csv", delimiter=",", names=True)
    assert len(h) == state.step and h["step"][-1] == state.step
    # the window, read back from the history: the packing did not move by phi_tolerance, and the
    # last contact solve missed its tolerance
    window = h[-STALL:]
    area = (window["xmax"] - window["xmin"]) * (window["ymax"] - window["ymin"])
    for name, values in (("phi", window["phi"]), ("box area", area)):  # within phi_tolerance = 1e-4 of one value
        assert np.ptp(values) <= 2e-4 * values[0], name
    assert window["nlgs_residual"][-1] > 1e-6 and np.median(window["nlgs_residual"]) > 1e-3
