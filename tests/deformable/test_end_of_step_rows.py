"""Segment–disk rows linearised at the end of the step (compute.contact.end_of_step), against the
exact distance of the disk's centre to the segment's line, computed here from the positions.

The scene of test_segment_disk_rows, frictionless: a T3 disk of radius 1 with a face on the +x
axis (turned by 0.02 rad), a rigid disk of radius 0.6 in front of that face. The soft disk turns at rate ω about its centre and the
rigid disk slides along the face: over a step h the face turns by about ω h, which the rows at
the step's start cannot see.
"""

import numpy as np
import pytest

from compute.contact import detection
from compute.contact.end_of_step import EndOfStepSegmentRows
from tests.deformable.test_segment_disk_rows import R_RIGID, _scene

H, OMEGA, SLIDE = 0.5, 0.02, 0.01
TURN = 0.02  # the soft disk turned a little, so that no entry of the face's row is exactly 0


def _line_gap(model, q, pairs) -> np.ndarray:
    """Distance of each pair's disk centre to its segment's line, minus the disk's radius (k,)."""
    x, c = model.soft_nodes(q), model.rigid.centres(q)
    a, b, d = x[pairs[:, 0]], x[model.loop_neighbours[pairs[:, 0], 1]], c[pairs[:, 1]]
    e = b - a
    cross = e[:, 0] * (d - a)[:, 1] - e[:, 1] * (d - a)[:, 0]
    return -cross / np.linalg.norm(e, axis=1) - model.rigid.radii[pairs[:, 1]]  # CCW loop: outside is to the right


def _turning(tmp_path, friction: float = 0.0):
    """(model, state, contacts, rows, v): the soft disk turning, the rigid disk sliding along y."""
    model, _, state, _, _ = _scene(tmp_path, "nodes_and_segments", 0.0, friction=friction, turn=TURN)
    detection.detect(model, state)
    contacts = detection.narrow_phase(model, state, branches=False)
    rows = EndOfStepSegmentRows.of_step(model, state, contacts, H, 1.0)
    v = np.zeros_like(state.q)
    x = model.soft[0].nodes(state.q)[0]
    model.soft[0].nodes(v)[0][:] = OMEGA * np.stack([-x[:, 1], x[:, 0]], axis=1)
    model.rigid.view(v)[0, 1] = SLIDE
    return model, state, contacts, rows, v


def _prediction(contacts, rows, dq) -> np.ndarray:
    c = rows.rows
    return contacts.gap[c] + np.sum(contacts.hn[c] * np.where(contacts.dof[c] >= 0, dq[contacts.dof[c]], 0.0), axis=1)


def test_relinearised_rows_predict_the_exact_gap_at_the_end_of_the_step(tmp_path):
    model, state, contacts, rows, v = _turning(tmp_path)
    assert rows is not None and len(rows.rows) >= 1  # the face's row
    q_end = state.q + H * v
    exact = _line_gap(model, q_end, rows.pairs)
    frozen = _prediction(contacts, rows, q_end - state.q)
    rows.relinearise(contacts, None, v)
    relinearised = _prediction(contacts, rows, q_end - state.q)
    assert np.max(np.abs(relinearised - exact)) < 1e-12
    # the rows of the step's start miss the face's turn by a second-order amount, far above that
    assert np.max(np.abs(frozen - exact)) > 1e-6


def test_relinearised_rows_carry_the_end_of_step_normal(tmp_path):
    model, state, contacts, rows, v = _turning(tmp_path)
    rows.relinearise(contacts, None, v)
    x = model.soft_nodes(state.q + H * v)
    a, b = x[rows.pairs[:, 0]], x[model.loop_neighbours[rows.pairs[:, 0], 1]]
    e = (b - a) / np.linalg.norm(b - a, axis=1)[:, None]
    assert np.allclose(contacts.normal[rows.rows], np.stack([e[:, 1], -e[:, 0]], axis=1), atol=1e-14)
    assert np.allclose(contacts.hn[rows.rows][:, 4:6], contacts.normal[rows.rows], atol=1e-14)  # on the disk


def test_at_the_steps_start_they_are_the_narrow_phase_rows(tmp_path):
    model, state, contacts, rows, _ = _turning(tmp_path)
    before = contacts.hn[rows.rows].copy(), contacts.gap[rows.rows].copy()
    rows.relinearise(contacts, None, np.zeros_like(state.q))  # θ = 1: q⁺ = q_n
    assert np.allclose(contacts.hn[rows.rows], before[0], atol=1e-15)
    assert contacts.gap[rows.rows] == pytest.approx(before[1], abs=1e-15)


def test_frictional_rows_keep_the_rows_of_the_steps_start(tmp_path):
    """With friction the lag's tangential force lies within the cone: no rows are made again."""
    _, _, _, rows, _ = _turning(tmp_path, friction=0.3)
    assert rows is None


def test_rows_are_made_again_in_full_steps_only(tmp_path, monkeypatch):
    """A cut step's sub-steps keep the rows of their start: the rows are made again in an attempt
    at the full time step h, not in one at h / 2 (compute.contact.end_of_step)."""
    from compute.bodies import Load

    model, stepper, state, _, _ = _scene(tmp_path, "nodes_and_segments", 0.0, friction=0.0, turn=TURN)
    model.rigid.view(state.v)[0, 0] = -SLIDE  # pressed into the face: the step needs Newton iterations
    made = []
    monkeypatch.setattr(EndOfStepSegmentRows, "relinearise", lambda self, *args: made.append(self.h))
    for h in (stepper.h, stepper.h / 2):
        stepper._attempt(state, Load(0.01, 0.0, stepper.gravity), h)
    assert made == [stepper.h]
