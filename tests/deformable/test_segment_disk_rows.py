"""Rigid disks against the straight boundary segments of soft bodies (``solver.rigid_soft_rows =
"nodes_and_segments"``), against circle geometry.

A T3 disk of radius 1 has a boundary segment (a face) centred on the +x axis, at x = x_f. A rigid
disk of radius r on the axis, its centre at x_f + r - d, overlaps the face by d: the
segment-disk row of that face has gap -d exactly, while the node-disk rows of the face's two
nodes (at distance sqrt((r - d)² + (L/2)²) from the centre) see no contact. Pressed onto the
face by the walls, the rigid disk rests on it with the segment rows and sinks between the face's
two nodes without them, overlapping the polygon by the circular segment that the chord cuts off
(area r² acos(c/r) - c √(r² - c²), c = √(r² - (L/2)²)).
"""

import numpy as np
import pytest

from compute.contact import detection
from post.measures import rigid_deformable_overlap
from tests.deformable import scenes

R_RIGID = 0.6


def _scene(folder, rows: str, gap: float, pressure: float = 0.01, friction: float = 0.3, turn: float = 0.0):
    """(model, stepper, state, x_f, L) of the soft disk and the rigid disk at ``gap`` from its face
    (the scene places it clear of the soft disk's circle; the state moves it there)."""
    p, cells = scenes.disk(30, "T3", turn=turn)
    face = p[np.argsort(p[:, 0])[-2:]]  # the two nodes of the face on the +x axis
    x_f, length = face[:, 0].mean(), abs(face[1, 1] - face[0, 1])
    params = scenes.parameters((-1.01, 1.0 + 2 * R_RIGID + 0.02, -1.02, 1.02), element="T3", friction=friction,
                               time_step=0.5, pressures=(pressure,), contact_tolerance=1e-8, newton_tolerance=1e-9)
    params["solver"]["rigid_soft_rows"] = rows
    scenes.write(folder, params, soft=[(p, cells)], rigid=[((1.0 + R_RIGID + 0.01, 0.0), R_RIGID)])
    model, stepper, state = scenes.load(folder)
    model.rigid.view(state.q)[0, 0] = x_f + R_RIGID + gap
    return model, stepper, state, x_f, length


def _family_rows(model, state, name: str):
    detection.detect(model, state)
    fam = next(f for f in model.families if f.name == name)
    return fam.rows(model, state.q, state.pairs[name], None)


def _overlap(model, state) -> float:
    g = model.soft[0]
    points = g.nodes(state.q)[0]
    cells = g.batch.cells
    return rigid_deformable_overlap(points, [(cells, np.zeros(len(cells), np.int64))],
                                    model.rigid.centres(state.q), model.rigid.radii)


def test_the_segment_row_of_a_face_has_the_distance_to_its_line_as_gap(tmp_path):
    d = 0.02
    model, _, state, x_f, length = _scene(tmp_path, "nodes_and_segments", -d)
    seg = _family_rows(model, state, "segment_disk")
    nodes = _family_rows(model, state, "node_disk")
    interior = seg.gap[np.abs(seg.normal[:, 1]) < 1e-12]  # the face's own row: normal along x
    assert interior.size == 1 and interior[0] == pytest.approx(-d, abs=1e-12)
    assert np.allclose(seg.normal[np.abs(seg.normal[:, 1]) < 1e-12], [1.0, 0.0])
    expected = np.hypot(R_RIGID - d, length / 2) - R_RIGID  # the face's nodes: outside the disk
    assert expected > 0 and np.all(nodes.gap >= expected * (1 - 1e-9))  # (no rows: none within the skin)
    assert np.all(seg.gap >= -d - 1e-12)


def test_without_segment_rows_there_is_no_such_family(tmp_path):
    model, *_ = _scene(tmp_path, "nodes", 0.0)
    assert "segment_disk" not in [f.name for f in model.families]
    assert "node_disk" in [f.name for f in model.families]


@pytest.mark.parametrize("rows", ["nodes", "nodes_and_segments"])
def test_a_pressed_rigid_disk_rests_on_the_face_only_with_segment_rows(tmp_path, rows):
    model, stepper, state, x_f, length = _scene(tmp_path, rows, 0.005)
    assert _overlap(model, state) < 1e-12
    state = scenes.settle(stepper, state, 0.01, 150, tol=1e-10)
    c = np.sqrt(R_RIGID**2 - (length / 2) ** 2)
    cap = R_RIGID**2 * np.arccos(c / R_RIGID) - c * np.sqrt(R_RIGID**2 - c**2)  # cut off by the face's chord
    overlap = _overlap(model, state)
    if rows == "nodes":
        assert overlap == pytest.approx(cap, rel=0.1)  # resting on the face's two nodes
    else:
        assert overlap < 1e-3 * cap
