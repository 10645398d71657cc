r"""Contact at small load: a disk squeezed between two rigid plates against the plane-strain
solution for a cylinder between plates (force per unit length F against approach delta).

Reference (Hertz line contact, superposing the two half-space solutions along the loaded
diameter and the uniform tension F/(pi R) that frees the rest of the circle, e.g. Johnson,
Contact Mechanics, Sec. 5.6; rigid plates):

    delta = (2 F / (pi E*)) (2 ln(4 R / a) - 1),   a = sqrt(4 F R / (pi E*)),   E* = E / (1 - nu^2),

valid for a << R (F / (E R) <= 0.02 here: a / R <= 0.14, delta / R <= 5.5 %). The plates are
the bottom and top walls, pushed by a pressure P over the box width W (F = P W); the side walls
are held far away. The disk is a T6 mesh with a boundary segment centred on each plate: the
approach is measured from first contact (box height = the mesh's height). The discrete contact
(nodes entering contact one by one) scatters delta by a few percent around the curve; below
about 600 elements (boundary segments longer than a / 2) the scatter exceeds 5 %.
"""

import numpy as np
import pytest

from tests.deformable import scenes

E, NU = scenes.E, scenes.NU
E_STAR = E / (1 - NU**2)
WIDTH = 6.0


def hertz_approach(force, radius=1.0):
    a = np.sqrt(4 * force * radius / (np.pi * E_STAR))
    return 2 * force / (np.pi * E_STAR) * (2 * np.log(4 * radius / a) - 1)


def squeeze(tmp_path, n, forces, max_steps=200):
    points, cells = scenes.disk(n, "T6", turn=np.pi / 2)
    bottom, top = points[:, 1].min(), points[:, 1].max()
    params = scenes.parameters((-WIDTH / 2, WIDTH / 2, bottom, top), time_step=10.0, newton_tolerance=1e-9,
                               contact_tolerance=1e-9)
    scenes.write(tmp_path, params, soft=[(points, cells)])
    model, stepper, state = scenes.load(tmp_path)
    scenes.pin_walls(stepper, (0, 1))
    out = []
    for force in forces:
        heights = []
        for _ in range(max_steps):
            state, _ = stepper.step(state, force / WIDTH)
            b = model.bounds(state.q)
            heights.append(b[3] - b[2])
            if len(heights) > 3 and max(abs(heights[-1] - heights[-2]), abs(heights[-2] - heights[-3])) < 1e-7:
                break
        else:
            raise AssertionError(f"F = {force}: no equilibrium in {max_steps} steps")
        f = scenes.wall_forces(model, state, stepper.h)
        np.testing.assert_allclose(f[2:], force, rtol=1e-5)  # the plates carry F
        out.append((top - bottom) - heights[-1])
    return np.array(out)


def test_cylinder_between_plates(tmp_path):
    forces = np.array([0.01, 0.02])
    delta = squeeze(tmp_path, 600, forces)
    np.testing.assert_allclose(delta, hertz_approach(forces), rtol=0.05)


@pytest.mark.slow
def test_cylinder_between_plates_fine(tmp_path):
    forces = np.array([0.0025, 0.005, 0.01, 0.02])
    delta = squeeze(tmp_path, 1000, forces, max_steps=400)
    np.testing.assert_allclose(delta, hertz_approach(forces), rtol=0.05)
