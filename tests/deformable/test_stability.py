"""Stability: a time step ten times too large, a pressure jump to P/E = 2, an element about to
invert: never a silent NaN. The stepper cuts the step (h/2, h/4, ...) or the run stops with a
diagnosis (step, body, elements) and what was written stays readable by post."""

import numpy as np
import pytest

from compute.errors import SimulationError
from compute.run import Run
from tests.deformable import scenes


def finite_history(out):
    import csv

    rows = list(csv.DictReader(open(out / "history.csv")))
    assert rows, "no history written"
    for r in rows:
        assert all(np.isfinite(float(v)) for k, v in r.items() if k not in ("inertial_number",)), r
    return rows


def test_time_step_ten_times_too_large(tmp_path):
    """h = 100 (the study's quasi-static h is 10): the stages still equilibrate (steps are cut
    when Newton fails) and every frame is finite."""
    pre = scenes.study_module("pre")
    pre.write(tmp_path / "scene", time_step=100.0, pressures=[1e-3, 0.1])
    run = Run(tmp_path / "scene", tmp_path / "out", log=lambda m: None)
    run.execute()
    finite_history(tmp_path / "out")
    from post.table import measure_output

    rows = measure_output(tmp_path / "out", min_contacts=1)
    assert [r["equilibrated"] for r in rows] == [1, 1]
    assert rows[-1]["P_walls"] == pytest.approx(0.1, rel=1e-6)
    assert 0.9 < rows[-1]["phi"] < 0.92


def test_pressure_jump_to_two_stops_with_a_diagnosis(tmp_path):
    """P/E = 1e-3, then straight to 2: the first stage is written; the jump cannot be taken even
    with h/16 (the walls hit the disk with a load of twice its Young modulus), so the run stops
    naming the step, the body and the elements; FAILED is written and frame 0 stays readable."""
    pre = scenes.study_module("pre")
    pre.write(tmp_path / "scene", pressures=[1e-3, 2.0])
    run = Run(tmp_path / "scene", tmp_path / "out", log=lambda m: None)
    with pytest.raises(SimulationError) as err:
        run.execute()
    msg = str(err.value)
    assert "body 0" in msg and "element" in msg and "step" in msg and "cut 4 times" in msg
    assert (tmp_path / "out" / "FAILED").read_text().strip() == msg
    finite_history(tmp_path / "out")
    from post.table import measure_output

    rows = measure_output(tmp_path / "out", min_contacts=1)
    assert len(rows) == 1 and rows[0]["equilibrated"] and np.isfinite(rows[0]["phi"])


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
        stepper.step(state, 0.0, 0.0)
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
