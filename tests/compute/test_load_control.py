"""The load control of a pressure stage (compute.stepping.load_control) with a scripted stepper
whose steps fail above a given load increment, and the run's honest end (compute.summary):
a stage ended by max_steps_per_stage, or contact solves above their tolerance, end INCOMPLETE."""

import json
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from compute.errors import SimulationError
from compute.run import Run
from compute.state import State
from compute.stepping import load_control
from compute.stepping.step_stats import StepStats, carrying
from pre.packing import polydisperse_radii, random_loose_packing
from pre.scene import default_parameters, write_scene


class ScriptedStepper:
    """Accepts a step (cuts included) when its pressure increment is at most ``limit``; records
    the pressures it was asked for."""

    def __init__(self, limit: float):
        self.limit, self.asked, self.p = limit, [], 0.0

    def step(self, state, pressure):
        self.asked.append(pressure)
        work = StepStats(newton_iterations=3, sweeps=40)  # every attempt works, failing ones too
        if pressure - self.p > self.limit + 1e-15:
            raise carrying(SimulationError(f"step {state.step + 1}: body 7: Newton did not converge"), work)
        self.p = pressure
        return replace(state, step=state.step + 1), SimpleNamespace(newton_iterations=3, sweeps=40, work=work)


def fresh_state():
    state = State(np.zeros(1), np.zeros(1), stage=1)
    load_control.start_stage(state)
    return state


def ramp(stepper, state, previous, target, max_steps=100):
    applied, halvings, reports = [], 0, []
    while state.load_fraction < 1.0 and len(applied) < max_steps:
        state, rep, p, k = load_control.controlled_step(stepper, state, previous, target, lambda m: None)
        applied.append(p)
        halvings += k
        reports.append(rep)
    ramp.reports, ramp.state = reports, state
    return applied, halvings


def test_a_jump_that_converges_is_one_step():
    stepper = ScriptedStepper(limit=10.0)
    applied, halvings = ramp(stepper, fresh_state(), 0.0, 1.0)
    assert applied == [1.0] and halvings == 0 and stepper.asked == [1.0]


def test_failing_jump_is_halved_then_grows_back():
    """Steps fail above an increment of 0.1 (of a jump 0 -> 1): 1, 1/2, 1/4, 1/8 fail, then
    1/16 steps are taken; after GROW_AFTER of them the increment doubles (1/8 fails again and
    is halved), ...; the pressures climb monotonically to exactly the target."""
    stepper = ScriptedStepper(limit=0.1)
    state = fresh_state()
    applied, halvings = ramp(stepper, state, 0.0, 1.0)
    assert applied[-1] == 1.0 and np.all(np.diff(applied) > 0) and np.all(np.diff(applied) <= 0.1 + 1e-12)
    assert applied[:2] == pytest.approx([1 / 16, 2 / 16])
    assert halvings >= 4
    assert ramp.state.load_fraction == 1.0
    first = ramp.reports[0]  # four failed increments, then the accepted one: all their work
    assert first.newton_iterations == 3 * 5 and first.sweeps == 40 * 5


def test_a_diagnosis_at_the_floor():
    """No increment works: the increment is halved down to its floor, and the run stops naming
    the stage, the pressure and the increment, with the step's own diagnosis."""
    stepper = ScriptedStepper(limit=-1.0)
    state = fresh_state()
    with pytest.raises(SimulationError) as err:
        load_control.controlled_step(stepper, state, 0.5, 1.0, lambda m: None)
    assert len(stepper.asked) == 11  # 1, 1/2, ..., 2^-10 of the jump
    assert err.value.work == StepStats(newton_iterations=3 * 11, sweeps=40 * 11)  # all the failed steps' work
    assert stepper.asked[-1] == pytest.approx(0.5 + 0.5 * load_control.MIN_INCREMENT)
    msg = str(err.value)
    assert "stage 1 (P = 1)" in msg and "body 7" in msg and "its floor" in msg
    assert f"{0.5 * load_control.MIN_INCREMENT:.3g}" in msg  # the increment in pressure units


def test_failure_at_full_load_stops():
    """After the ramp (λ = 1) there is no increment left to split: the step's failure (after its
    own cuts) stops the run."""
    stepper = ScriptedStepper(limit=-1.0)
    state = fresh_state()
    state.load_fraction = 1.0
    with pytest.raises(SimulationError, match="stage load fully applied"):
        load_control.controlled_step(stepper, state, 0.0, 1.0, lambda m: None)
    assert stepper.asked == [1.0]


def rigid_scene(folder, **solver):
    rng = np.random.default_rng(3)
    radii = polydisperse_radii(30, rng=rng)
    centres, box = random_loose_packing(radii, 0.5, rng)
    p = default_parameters(box, 0.3, 1.0, [1.0, 2.0])
    p["solver"].update(time_step=0.1, **solver)
    return write_scene(folder, p, centres, radii, ["rigid"] * 30), p


def test_max_steps_and_contact_misses_end_incomplete(tmp_path):
    """Stages cut short by max_steps_per_stage, and contact solves capped at 3 sweeps: the run
    goes through its program but writes INCOMPLETE (not COMPLETE) with the reasons, and
    summary.json counts them as history.csv shows them."""
    scene, p = rigid_scene(tmp_path / "scene", nlgs_max_sweeps=3)
    text = (scene / "scene.toml").read_text().replace(f"max_steps_per_stage = {p['loading']['max_steps_per_stage']}",
                                                      "max_steps_per_stage = 300")
    (scene / "scene.toml").write_text(text)
    logs = []
    Run(scene, tmp_path / "out", log=logs.append).execute()
    out = tmp_path / "out"
    assert not (out / "COMPLETE").exists() and (out / "INCOMPLETE").is_file()
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "incomplete" and summary["stages_not_equilibrated"] == [0, 1]
    import csv

    history = list(csv.DictReader(open(out / "history.csv")))
    misses = sum(float(r["nlgs_residual"]) > p["solver"]["contact_tolerance"] for r in history)
    assert misses > 0 and summary["contact_misses"] == misses and summary["steps"] == len(history) == 600
    assert any(m.startswith("WARNING: run INCOMPLETE") for m in logs)
    assert "not equilibrated" in (out / "INCOMPLETE").read_text()


def test_equilibrated_run_is_complete(tmp_path):
    """Enough sweeps for every contact solve to reach its tolerance (2000, the default, leave
    about one step in ten of this compaction above it: then the run would be INCOMPLETE)."""
    scene, _ = rigid_scene(tmp_path / "scene", nlgs_max_sweeps=100_000)
    Run(scene, tmp_path / "out", log=lambda m: None).execute()
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert (tmp_path / "out" / "COMPLETE").is_file() and summary["status"] == "complete"
    assert summary["contact_misses"] == 0 and all(s["equilibrated"] for s in summary["stages"])


def test_a_stage_ends_at_the_first_step_that_passes_the_test(tmp_path):
    """The stage-end test over a sliding window (compute.run), recomputed from history.csv: each
    stage ends at the first step with its full load at which φ differs from φ check_every steps
    before by less than phi_tolerance (relative) and the inertial number is below
    inertial_tolerance (the wall force-balance test switched off: history.csv does not hold
    the wall forces)."""
    import csv

    from pre.scene import copy_scene

    source, p = rigid_scene(tmp_path / "scene", nlgs_max_sweeps=100_000)
    scene = copy_scene(source, tmp_path / "window", {"loading.force_tolerance": 0.0})
    Run(scene, tmp_path / "out", log=lambda m: None).execute()
    history = list(csv.DictReader(open(tmp_path / "out" / "history.csv")))
    window, tol = p["loading"]["check_every"], p["loading"]["phi_tolerance"]
    for stage, target in enumerate(p["loading"]["pressures"]):
        rows = [r for r in history if int(r["stage"]) == stage]
        phi = np.array([float(r["phi"]) for r in rows])
        passes = [k >= window and float(rows[k]["pressure_applied"]) == target
                  and abs(phi[k] - phi[k - window]) < tol * phi[k] and float(rows[k]["inertial_number"]) < tol
                  for k in range(len(rows))]
        assert passes[-1] and not any(passes[:-1]), stage
