"""Stability: time steps 10 and 100 times too large, pressure jumps to P/E = 2 and 5, friction
μ = 1, an element about to invert: never a silent NaN. The load control splits the load increment, the stepper cuts the
step (h/2, h/4, ...), or the run stops with a diagnosis (stage, increment, step, body, elements)
and what was written stays readable by post."""

import numpy as np
import pytest

from compute.errors import SimulationError
from compute.run import Run
from pre import single_particle
from tests.deformable import scenes


def finite_history(out):
    import csv

    rows = list(csv.DictReader(open(out / "history.csv")))
    assert rows, "no history written"
    for r in rows:
        assert all(np.isfinite(float(v)) for k, v in r.items() if k not in ("inertial_number",)), r
    return rows


@pytest.mark.parametrize("h, elements", [(100.0, single_particle.ELEMENTS), (1000.0, 92)])
def test_time_step_far_too_large(tmp_path, h, elements):
    """h = 100 and 1000 (the study's quasi-static h is 10): the stages still equilibrate (steps
    are cut when Newton fails), every frame is finite, and the equilibrium at P/E = 0.1 is the one
    reached with h = 10 (within 1e-3: these meshes have equilibria there up to 7.5e-4 apart).
    h = 1000 on the 92-element disk: on the default 101-element disk h = 300 and 1000 stop, Newton
    not converging in its 40 iterations (test below)."""
    from post.table import measure_output

    phi = {}
    for step in (h, 10.0):
        folder = tmp_path / f"h{step:g}"
        single_particle.write(folder / "scene", elements=elements, time_step=step, pressures=[1e-3, 0.1])
        Run(folder / "scene", folder / "out", log=lambda m: None).execute()
        finite_history(folder / "out")
        rows = measure_output(folder / "out", min_contacts=1)
        assert [r["equilibrated"] for r in rows] == [1, 1]
        assert rows[-1]["P_walls"] == pytest.approx(0.1, rel=1e-5)
        phi[step] = rows[-1]["phi"]
    assert phi[h] == pytest.approx(phi[10.0], abs=1e-3)


def test_time_step_far_too_large_default_disk(tmp_path):
    """h = 1000 on the default disk: the run equilibrates or stops with a diagnosis that names
    the stage and the load increment; never NaN, and what it wrote stays readable by post."""
    from post.table import measure_output

    single_particle.write(tmp_path / "scene", time_step=1000.0, pressures=[1e-3, 0.1])
    try:
        Run(tmp_path / "scene", tmp_path / "out", log=lambda m: None).execute()
    except SimulationError as exc:
        assert "stage 1 (P = 0.1)" in str(exc) and "load increment" in str(exc)
    finite_history(tmp_path / "out")
    assert measure_output(tmp_path / "out", min_contacts=1)[0]["equilibrated"] == 1


def test_friction_one_comes_to_rest(tmp_path):
    """Three soft disks pressed together with μ = 1 (a large h, tight tolerances): no cut, no
    NaN; at rest every wall carries P times its length (its equation of motion at zero
    velocity) and every impulse lies in its Coulomb cone, some sticking inside it."""
    model, stepper, state = scenes.pressed_three(tmp_path, 1.0, 1.0, contact_tolerance=1e-8)
    state = scenes.settle(stepper, state, 0.05, 300)
    assert np.isfinite(state.q).all() and stepper.stats["cuts"] == 0
    b = model.bounds(state.q)
    lengths = np.array([b[3] - b[2], b[3] - b[2], b[1] - b[0], b[1] - b[0]])
    np.testing.assert_allclose(scenes.wall_forces(model, state, stepper.h), 0.05 * lengths, rtol=1e-5)
    r = stepper.step(state, 0.05)[1].contacts.impulse
    on = r[:, 0] > 0.0
    assert np.all(np.abs(r[on, 1]) <= 1.0 * r[on, 0] * (1 + 1e-12))
    assert np.any(np.abs(r[on, 1]) < 0.99 * r[on, 0])


def equilibrium(tmp_path, name, pressures):
    """The measures (post.table) of the last equilibrated stage of the single particle run
    through ``pressures``, and the run's history rows."""
    from post.table import measure_output
    single_particle.write(tmp_path / name / "scene", pressures=pressures)
    Run(tmp_path / name / "scene", tmp_path / name / "out", log=lambda m: None).execute()
    assert (tmp_path / name / "out" / "COMPLETE").is_file()
    rows = measure_output(tmp_path / name / "out", min_contacts=1)
    assert all(r["equilibrated"] for r in rows)
    return rows[-1], finite_history(tmp_path / name / "out")


@pytest.mark.parametrize("target", [0.4, 1.0])
def test_pressure_jump_is_taken_by_load_increments(tmp_path, target):
    """P/E = 1e-3, then straight to 0.4 (taken by cutting h) or 1 (the Young modulus at once: the
    jump is split into load increments that climb monotonically to the target); the stage ends
    in an equilibrium: the pressure from the contact forces (granular stress) equals the applied
    one.
    At 0.4 the disk's area equals that of a program climbing there through four stages (the
    nearly incompressible disk's area follows from its mean stress; its shape need not: the
    two paths end with the corners filled differently, φ 0.9875 and 0.9810, both equilibria).
    (A jump to 2 no longer ends: past P/E ~ 1 this mesh's curved edges cross the walls between
    their nodes and φ passes 1, where the run stops, compute/wall_crossing.py.)"""
    jump, rows = equilibrium(tmp_path, "jump", [1e-3, target])
    assert jump["P"] == pytest.approx(target, rel=1e-5) and jump["P_walls"] == pytest.approx(target, rel=1e-5)
    if target < 1.0:
        path, _ = equilibrium(tmp_path, "path", [1e-3, 0.01, 0.05, 0.15, target])
        assert jump["phi"] * jump["volume"] == pytest.approx(path["phi"] * path["volume"], rel=2e-4)
    stage1 = [r for r in rows if r["stage"] == "1"]
    applied = [float(r["pressure_applied"]) for r in stage1]
    assert applied == sorted(applied) and applied[-1] == target
    if target >= 1.0:
        assert sum(int(r["load_halvings"]) for r in stage1) > 0 and 1e-3 < applied[0] < target


def test_pressure_jump_to_five_is_taken_or_stopped_with_a_diagnosis(tmp_path):
    """P/E = 0.01 straight to 5: either load increments reach it, or the run stops naming the
    stage, the load increment and the body, or the step whose φ passes 1 and the body whose
    boundary crosses a wall (compute.wall_crossing); never a NaN, and what was written stays
    readable."""
    single_particle.write(tmp_path / "scene", pressures=[0.01, 5.0])
    run = Run(tmp_path / "scene", tmp_path / "out", log=lambda m: None)
    try:
        run.execute()
    except SimulationError as exc:
        msg = str(exc)
        load_control = "stage 1 (P = 5)" in msg and "load increment" in msg
        crossing = "(stage 1, P = " in msg and "> 1: body 0's boundary crosses wall" in msg
        assert (load_control or crossing) and "body 0" in msg, msg
        assert (tmp_path / "out" / "FAILED").read_text().strip() == msg
    finite_history(tmp_path / "out")
    from post.table import measure_output

    rows = measure_output(tmp_path / "out", min_contacts=1)
    assert rows[0]["equilibrated"] and all(np.isfinite(r["phi"]) for r in rows)


def kicked(tmp_path, speed):
    """A free T6 disk whose interior node nearest the centre is thrown at ``speed``."""
    params = scenes.parameters((-5.0, 5.0, -5.0, 5.0), time_step=0.1, theta=0.5, control="velocity")
    scenes.write(tmp_path, params, soft=[scenes.disk(92, "T6")])
    model, stepper, state = scenes.load(tmp_path)
    x = scenes.body_nodes(model, state.q)
    node = int(np.argmin(np.linalg.norm(x, axis=1)))
    scenes.body_nodes(model, state.v)[node, 0] = speed
    return model, stepper, state


def test_element_about_to_invert_is_cut(tmp_path):
    """A kick that would invert elements within one step of h = 0.1: the step is cut and the
    motion stays admissible (every element keeps J > 0)."""
    model, stepper, state = kicked(tmp_path, 3.0)
    for _ in range(5):
        state, _ = stepper.step(state, 0.0, 0.0)
        assert np.all(np.isfinite(state.q)) and np.all(np.isfinite(state.v))
        assert scenes.fe_body(model).inverted_elements(scenes.body_nodes(model, state.q)).size == 0
    assert stepper.stats["cuts"] > 0


def test_element_inverting_whatever_the_step_stops_with_a_diagnosis(tmp_path):
    model, stepper, state = kicked(tmp_path, 1e4)
    q0, v0 = state.q.copy(), state.v.copy()
    with pytest.raises(SimulationError, match=r"step 1: body 0: .*element\(s\).*\[\d+"):
        stepper.step(state, 0.0, 0.0)
    np.testing.assert_array_equal(state.q, q0)  # the failed step left the state as it was
    np.testing.assert_array_equal(state.v, v0)


def test_contact_misses_at_the_deepest_cut_are_kept_and_reported(tmp_path):
    """Contact solves capped at one NLGS sweep (tolerance 1e-10) miss at every depth: each step
    is cut down to h / 2**MAX_CUTS, where the misses no longer fail it; the step is taken, its reported
    residual is above the tolerance (what makes a run INCOMPLETE) and the state stays finite."""
    from dataclasses import replace

    from compute import solvers

    model, stepper, state = scenes.pressed_three(tmp_path, 0.3, 1.0, contact_tolerance=1e-10)
    stepper.solver = solvers.for_model(replace(model.scene.solver, nlgs_max_sweeps=1, contact="nlgs"), model)
    reports = []
    for _ in range(3):
        state, rep = stepper.step(state, 0.05)
        reports.append(rep)
    deepest = 2**stepper.MAX_CUTS
    assert [r.sub_steps for r in reports][1:] == [deepest, deepest] and reports[0].cuts == stepper.MAX_CUTS
    assert all(r.residual > 1e-10 for r in reports) and np.isfinite(state.q).all()
    assert state.time == pytest.approx(3.0)
