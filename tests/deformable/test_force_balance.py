"""Force balance through deformable contacts: a disk resting on a wall under gravity, a rigid
disk and a deformable disk stacked between two plates, two deformable disks stacked (node to
segment, both directions)."""

import numpy as np
import pytest

from compute.contact import detection
from tests.deformable import scenes

WIDTH = 6.0


def settle(model, stepper, state, pressure, max_steps=300, tol=1e-10):
    last = []
    for _ in range(max_steps):
        state, _ = stepper.step(state, pressure, 0.0)
        last.append(state.q.copy())
        if len(last) > 2 and max(np.abs(last[-1] - last[-2]).max(), np.abs(last[-2] - last[-3]).max()) < tol:
            return state
    raise AssertionError(f"no rest in {max_steps} steps")


def family_forces(model, state, h, family):
    """Sum over the contacts of one deformable family of the force on body j, (2,)."""
    c = detection.narrow_phase(model, state)
    k = 0
    for f in (fam.name for fam in model.families):
        m = len(state.pairs[f])
        if f == family:
            sl = slice(k, k + m)
            t = np.column_stack([-c.normal[sl, 1], c.normal[sl, 0]])
            return ((c.impulse[sl, :1] * c.normal[sl] + c.impulse[sl, 1:] * t) / h).sum(axis=0)
        k += m
    raise KeyError(family)


@pytest.mark.parametrize("element", ["T3", "T6"])
def test_disk_on_a_wall_under_gravity(tmp_path, element):
    points, cells = scenes.disk(92, element, turn=np.pi / 2)
    g = 1e-3
    params = scenes.parameters((-3.0, 3.0, points[:, 1].min(), 4.0), element=element, time_step=10.0,
                               control="velocity", gravity=(0.0, -g))
    scenes.write(tmp_path, params, soft=[(points, cells)])
    model, stepper, state = scenes.load(tmp_path)
    state = settle(model, stepper, state, 0.0)
    weight = g * scenes.fe_body(model).mass.sum() / 2  # sum of M's entries = 2 x mass
    forces = scenes.wall_forces(model, state, stepper.h)
    assert forces[2] == pytest.approx(weight, rel=1e-8)
    assert np.abs(forces[[0, 1, 3]]).max() == 0.0
    assert stepper.stats["cuts"] == 0


@pytest.mark.parametrize("friction", [0.0, 0.3])
def test_rigid_disk_pressed_on_a_deformable_disk(tmp_path, friction):
    """Plate - deformable disk - rigid disk - plate in a channel as wide as the disks (side
    walls held still; without them a frictionless stack of two disks buckles sideways): the
    soft-rigid contacts carry the plates' force."""
    points, cells = scenes.disk(92, "T6", turn=np.pi / 2)
    bottom, top = points[:, 1].min(), points[:, 1].max()
    left, right = points[:, 0].min(), points[:, 0].max()
    r = min(-left, right) - 1e-3
    centre = (0.0, top + r + 1e-3)
    params = scenes.parameters((left, right, bottom, centre[1] + r), time_step=10.0, friction=friction)
    scenes.write(tmp_path, params, soft=[(points, cells)], rigid=[(centre, r)])
    model, stepper, state = scenes.load(tmp_path)
    scenes.pin_walls(stepper, (0, 1))
    force = 0.01
    state = settle(model, stepper, state, force / (right - left), tol=1e-9)
    walls = scenes.wall_forces(model, state, stepper.h)
    b = model.bounds(state.q)
    np.testing.assert_allclose(walls[2:], force / (right - left) * (b[1] - b[0]), rtol=1e-6)
    on_disk = family_forces(model, state, stepper.h, "node_disk")  # force of the soft disk on the rigid one
    assert on_disk[1] == pytest.approx(walls[3], rel=1e-5)
    # horizontally the rigid disk may lean on a side wall (the mesh is not symmetric)
    assert abs(on_disk[0]) <= max(walls[0], walls[1]) * (1 + 1e-6) + 1e-12


@pytest.mark.slow
def test_two_deformable_disks_stacked(tmp_path):
    """Plate - T6 disk - T6 disk - plate in a channel as wide as the disks: node-to-segment
    contacts (both directions) carry the plates' force. Slow (about 30 s): the two-pass
    node-to-segment constraints are redundant where the boundaries touch, which the NLGS
    stopping test (relative impulse change) converges slowly on."""
    a = scenes.disk(92, "T6", turn=np.pi / 2)
    lo, hi = a[0][:, 1].min(), a[0][:, 1].max()
    left, right = a[0][:, 0].min(), a[0][:, 0].max()
    b = scenes.disk(92, "T6", centre=(0.0, hi - lo + 1e-3), turn=np.pi / 2)
    params = scenes.parameters((left, right, lo, b[0][:, 1].max()), time_step=10.0)
    scenes.write(tmp_path, params, soft=[a, b])
    model, stepper, state = scenes.load(tmp_path)
    scenes.pin_walls(stepper, (0, 1))
    force = 0.01
    state = settle(model, stepper, state, force / (right - left), tol=1e-9)
    walls = scenes.wall_forces(model, state, stepper.h)
    c = detection.narrow_phase(model, state)
    seg = c.body_j >= 0
    assert set(np.unique(c.body_i[seg & (c.impulse[:, 0] > 0)])) == {0, 1}  # both directions work
    t = np.column_stack([-c.normal[:, 1], c.normal[:, 0]])
    f = (c.impulse[:, :1] * c.normal + c.impulse[:, 1:] * t) / stepper.h
    # force on the upper disk (body 1) from the lower one (body 0), whichever is i or j
    on_upper = np.where((c.body_j == 1)[:, None], f, -f)[seg].sum(axis=0)
    assert on_upper[1] == pytest.approx(walls[3], rel=1e-5)
    assert walls[2] == pytest.approx(walls[3], rel=1e-6)
