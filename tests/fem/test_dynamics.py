"""theta-scheme Newton system: consistency, momentum balance of a free spinning, vibrating disk.

The internal force of a step is evaluated at x_theta = x_n + theta h ((1 - theta) v_n + theta v_new):
the implicit midpoint rule at theta = 1/2 (linear and angular momentum conserved exactly),
backward Euler at theta = 1.
"""

import numpy as np
import pytest

from compute.fem import FEBody, NeoHookean

from .meshes import mesh
from .newton import newton

MATERIAL = NeoHookean(young=1.0, poisson=0.3, density=1.0)


@pytest.fixture(scope="module")
def disk() -> FEBody:
    X, cells = mesh("T6", "disk")
    return FEBody(X, cells, "T6", MATERIAL, "mean_dilatation")


def initial_velocity(X: np.ndarray) -> np.ndarray:
    """Translation + spin (omega = 1) + radial breathing, (2n,)."""
    return (np.array([0.3, -0.2]) + np.column_stack([-X[:, 1], X[:, 0]]) + 0.2 * X).reshape(-1)


def momenta(body: FEBody, x: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, float]:
    """Linear momentum (2,) and angular momentum sum_ab m_ab x_a x v_b about the origin."""
    p = (body.mass @ v).reshape(-1, 2)
    return p.sum(axis=0), float(np.sum(x[:, 0] * p[:, 1] - x[:, 1] * p[:, 0]))


def theta_run(body: FEBody, h: float, steps: int, theta: float) -> tuple[np.ndarray, np.ndarray]:
    """Free motion with the library's theta-scheme system; returns final (x (n, 2), v (2n,))."""
    x, v = body.X.copy(), initial_velocity(body.X)
    zero = np.zeros(body.n_dof)
    for _ in range(steps):
        def system(u):
            s = body.theta_system(u, x, v, zero, zero, h, theta)
            return s.residual, s.matrix

        u = newton(system, v, 1e-14)
        x, v = body.theta_system(u, x, v, zero, zero, h, theta).x_new, u
    return x, v


def midpoint_run(body: FEBody, h: float, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """Implicit midpoint rule, M (v+ - v-) = -h f_int((x- + x+)/2), x+ = x- + h (v- + v+)/2."""
    x, v = body.X.copy(), initial_velocity(body.X)
    for _ in range(steps):
        def system(u):
            f, K = body.internal_force_and_tangent(x + 0.25 * h * (v + u).reshape(-1, 2))
            return body.mass @ (u - v) + h * f, body.mass + 0.25 * h * h * K

        u = newton(system, v, 1e-14)
        x, v = x + 0.5 * h * (v + u).reshape(-1, 2), u
    return x, v


@pytest.mark.parametrize("theta", [0.5, 0.8])
def test_matrix_is_the_residual_derivative(disk, theta):
    rng = np.random.default_rng(4)
    x = disk.X + 0.05 * rng.uniform(-1, 1, disk.X.shape)
    v_n, v_new = 0.2 * rng.normal(size=(2, disk.n_dof))
    f_ext_n, f_ext_new = rng.normal(size=(2, disk.n_dof))
    args = (x, v_n, f_ext_n, f_ext_new, 0.1, theta)
    state = disk.theta_system(v_new, *args)
    eps = 1e-6
    fd = np.empty((disk.n_dof, disk.n_dof))
    for j in range(disk.n_dof):
        dv = np.zeros(disk.n_dof)
        dv[j] = eps
        plus, minus = disk.theta_system(v_new + dv, *args), disk.theta_system(v_new - dv, *args)
        fd[:, j] = (plus.residual - minus.residual) / (2 * eps)
    A = state.matrix.toarray()
    assert np.abs(A - fd).max() / np.abs(A).max() < 1e-8
    x_new = x + 0.1 * ((1 - theta) * v_n + theta * v_new).reshape(-1, 2)
    np.testing.assert_allclose(state.x_new, x_new)
    np.testing.assert_allclose(state.x_theta, x + theta * (x_new - x))
    np.testing.assert_array_equal(state.f_int, disk.internal_force(state.x_theta))


def test_uniform_body_force_gives_free_fall(disk):
    """f_ext = M g (consistent body force): v+ = v- + h g exactly, no deformation."""
    g = np.tile([0.0, -9.81], disk.n_nodes)
    v = np.tile([1.0, 0.5], disk.n_nodes)
    f_ext = disk.mass @ g
    h = 0.01
    state = disk.theta_system(v + h * g, disk.X, v, f_ext, f_ext, h, 0.5)
    assert np.abs(state.residual).max() < 1e-14


@pytest.mark.parametrize("theta", [0.5, 1.0])
def test_theta_scheme_conserves_linear_momentum(disk, theta):
    p0, _ = momenta(disk, disk.X, initial_velocity(disk.X))
    x, v = theta_run(disk, 0.05, 100, theta)
    p, _ = momenta(disk, x, v)
    assert np.abs(p - p0).max() <= 1e-10 * np.abs(p0).max()


def test_theta_half_conserves_angular_momentum(disk):
    """theta = 1/2 evaluates f_int at the midpoint: L is conserved to round-off over 100 steps
    of a translating, spinning, breathing disk (and it did move and spin)."""
    p0, L0 = momenta(disk, disk.X, initial_velocity(disk.X))
    x, v = theta_run(disk, 0.05, 100, 0.5)
    p, L = momenta(disk, x, v)
    assert np.abs(p - p0).max() <= 1e-10 * np.abs(p0).max()
    assert abs(L - L0) <= 1e-10 * abs(L0)
    assert np.linalg.norm(x - disk.X, axis=1).max() > 1.0


def test_theta_half_is_the_midpoint_rule(disk):
    """Same trajectory as an independent implementation of the implicit midpoint rule."""
    x, v = theta_run(disk, 0.05, 20, 0.5)
    xm, vm = midpoint_run(disk, 0.05, 20)
    assert np.abs(x - xm).max() < 1e-10 and np.abs(v - vm).max() < 1e-9


def test_theta_one_dissipates_energy(disk):
    """Backward Euler (theta = 1) loses kinetic + strain energy every step (no gain)."""
    x, v = disk.X.copy(), initial_velocity(disk.X)
    zero = np.zeros(disk.n_dof)

    def energy(x, v):
        return 0.5 * v @ (disk.mass @ v) + disk.strain_energy(x)

    e = [energy(x, v)]
    for _ in range(20):
        def system(u):
            s = disk.theta_system(u, x, v, zero, zero, 0.05, 1.0)
            return s.residual, s.matrix

        u = newton(system, v, 1e-13)
        x, v = disk.theta_system(u, x, v, zero, zero, 0.05, 1.0).x_new, u
        e.append(energy(x, v))
    assert np.all(np.diff(e) <= 1e-12 * e[0]) and e[-1] < e[0]


def test_midpoint_rule_conserves_both_momenta(disk):
    """Exact conservation with the discrete forces evaluated at the midpoint: it checks that
    f_int sums to zero and has no torque (sum_a x_a x f_a = 0) at every configuration."""
    p0, L0 = momenta(disk, disk.X, initial_velocity(disk.X))
    x, v = midpoint_run(disk, 0.05, 100)
    p, L = momenta(disk, x, v)
    assert np.abs(p - p0).max() <= 1e-10 * np.abs(p0).max()
    assert abs(L - L0) <= 1e-10 * abs(L0)
    assert np.linalg.norm(x - disk.X, axis=1).max() > 1.0  # it did move and spin
