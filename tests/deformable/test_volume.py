r"""Volume: the disk's area change under the walls' pressure against the 2D bulk response.

Independent reference (small strain, plane strain). For any body in equilibrium under
boundary forces f_c at points x_c, the mean Cauchy stress is sigma_bar = (1/A) sum_c x_c (x) f_c
(divergence theorem; the finite-element equilibrium satisfies it exactly, since
sum_a x_a (x) dN_a/dx = I). In the single-particle box the four walls push with P L each at
distance L/2 from the centre, so sigma_bar = -(P L^2 / A) I = -(P / phi) I in the plane.
Linear plane-strain elasticity relates the in-plane mean stress s = (s_xx + s_yy)/2 to the
area strain e_A = e_xx + e_yy through the 2D bulk modulus K_2D = lambda + mu = kappa + mu/3
(the law's small-strain Lame constants are kappa - 2 mu/3 and mu), and a homogeneous body's
mean strain is the compliance applied to its mean stress, whatever the stress field. Hence

    Delta A / A_0 = -P / (phi K_2D),   K_2D = E / (3 (1 - 2 nu)) + E / (6 (1 + nu)),

E = 1, nu = 0.495: K_2D = 33.44 E, about 100 times the shear modulus, so that the area
changes by 4e-5 at P/E = 1e-3 while the disk flattens by 1 % against the walls.
"""

import numpy as np
import pytest

from pre import single_particle
from tests.deformable import scenes


def settle(model, stepper, state, pressure, max_steps=200, tol=1e-10):
    phi = [model.phi(state.q)]
    for _ in range(max_steps):
        state, _ = stepper.step(state, pressure)
        phi.append(model.phi(state.q))
        if len(phi) > 3 and max(abs(phi[-1] - phi[-2]), abs(phi[-2] - phi[-3])) < tol * phi[-1]:
            return state
    raise AssertionError(f"no equilibrium in {max_steps} steps (last phi changes {np.diff(phi[-4:])})")


@pytest.mark.parametrize("element,n", [("T6", 92), ("T3", 92)])
def test_area_change_is_the_2d_bulk_response(tmp_path, element, n):
    single_particle.write(tmp_path / "scene", element=element, elements=n, pressures=[1e-3], newton_tolerance=1e-10,
              contact_tolerance=1e-10)
    model, stepper, state = scenes.load(tmp_path / "scene")
    body = scenes.fe_body(model)
    a0 = body.area(body.X)
    mat = body.material
    k2d = mat.kappa + mat.mu / 3.0
    for pressure in (1e-3, 3e-3):
        state = settle(model, stepper, state, pressure)
        a = body.area(scenes.body_nodes(model, state.q))
        expected = -pressure / (model.phi(state.q) * k2d)
        assert (a - a0) / a0 == pytest.approx(expected, rel=0.02)
        # the walls carry the applied pressure (equilibrium of each wall)
        b = model.bounds(state.q)
        f = scenes.wall_forces(model, state, stepper.h)
        lengths = np.array([b[3] - b[2], b[3] - b[2], b[1] - b[0], b[1] - b[0]])
        np.testing.assert_allclose(f / lengths, pressure, rtol=1e-6)
