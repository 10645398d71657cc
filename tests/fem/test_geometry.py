"""Mass matrix, area, centroid, boundary loop, inverted-element detection, input validation."""

import numpy as np
import pytest

from compute.fem import T3, T6, FEBody, InvertedElementError, NeoHookean, boundary_loop

from .meshes import disk_mesh, mesh, square_mesh, to_t6

MATERIAL = NeoHookean(young=1.0, poisson=0.3, density=2.5)
F_AFFINE = np.array([[1.3, 0.4], [-0.2, 0.8]])
C_AFFINE = np.array([0.7, -1.1])


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """z-component of the cross product of 2D vectors (..., 2)."""
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def body(X, cells, element, volumetric="standard"):
    return FEBody(X, cells, element, MATERIAL, volumetric)


def boundary_integrals(x: np.ndarray, loop: np.ndarray, element: str) -> tuple[float, np.ndarray]:
    """Area and centroid by Green's theorem along the (parabolic for T6) boundary edges, with
    3-point Gauss-Legendre, exact for the degree-5 integrands x^2 dy of a parabolic edge."""
    ends = loop[::2] if element == "T6" else loop
    p0 = x[ends]
    p1 = x[np.roll(ends, -1)]
    pm = x[loop[1::2]] if element == "T6" else 0.5 * (p0 + p1)
    t, w = np.polynomial.legendre.leggauss(3)
    t, w = 0.5 * (t + 1.0), 0.5 * w
    pos = (p0[:, None] * ((1 - t) * (1 - 2 * t))[:, None] + p1[:, None] * (t * (2 * t - 1))[:, None]
           + pm[:, None] * (4 * t * (1 - t))[:, None])
    vel = (p0[:, None] * (4 * t - 3)[:, None] + p1[:, None] * (4 * t - 1)[:, None]
           + pm[:, None] * (4 - 8 * t)[:, None])
    area = np.sum(w * pos[..., 0] * vel[..., 1])
    cx = np.sum(w * pos[..., 0] ** 2 * vel[..., 1]) / (2 * area)
    cy = -np.sum(w * pos[..., 1] ** 2 * vel[..., 0]) / (2 * area)
    return area, np.array([cx, cy])


def curved_t6_disk(seed=3):
    """2-ring T6 disk, curved boundary, every node perturbed: no symmetry left."""
    X, cells = to_t6(*disk_mesh(2), circle_radius=1.0)
    X = X + 0.04 * np.random.default_rng(seed).uniform(-1, 1, X.shape)
    return X, cells


@pytest.mark.parametrize("element", ["T3", "T6"])
def test_area_and_centroid_against_boundary_integrals(element):
    X, cells = curved_t6_disk() if element == "T6" else mesh("T3", "patch")
    b = body(X, cells, element)
    for x in (X, X @ F_AFFINE.T + C_AFFINE, X + 0.05 * np.sin(2.0 * X[:, ::-1])):
        area, centroid = boundary_integrals(x, b.boundary, element)
        assert b.area(x) == pytest.approx(area, rel=1e-13)
        np.testing.assert_allclose(b.centroid(x), centroid, rtol=1e-12, atol=1e-13)
    assert b.area(X @ F_AFFINE.T) == pytest.approx(np.linalg.det(F_AFFINE) * b.area(X), rel=1e-13)
    np.testing.assert_allclose(b.reference_areas.sum(), b.area(X), rtol=1e-14)


@pytest.mark.parametrize("element", ["T3", "T6"])
def test_mass_integrates_rigid_translations(element):
    X, cells = curved_t6_disk() if element == "T6" else mesh("T3", "disk")
    b = body(X, cells, element)
    total = MATERIAL.density * b.area(X)
    M = b.mass
    ex, ey = np.tile([1.0, 0.0], b.n_nodes), np.tile([0.0, 1.0], b.n_nodes)
    assert ex @ M @ ex == pytest.approx(total, rel=1e-13)
    assert ey @ M @ ey == pytest.approx(total, rel=1e-13)
    assert ex @ M @ ey == 0.0
    assert abs(M - M.T).max() <= 1e-15 * abs(M).max()
    assert np.linalg.eigvalsh(M.toarray()).min() > 0.0


def test_t3_element_mass_is_analytic():
    X = np.array([[0.1, 0.2], [1.3, -0.1], [0.4, 0.9]])
    b = body(X, np.array([[0, 1, 2]]), "T3")
    area = 0.5 * cross(X[1] - X[0], X[2] - X[0])
    expected = MATERIAL.density * area / 12 * (np.ones((3, 3)) + np.eye(3))
    np.testing.assert_allclose(b.mass.toarray()[::2, ::2], expected, rtol=1e-14)


def test_straight_t6_element_mass_is_analytic():
    """rho A / 180 [[6 -1 -1 0 -4 0], ...]: exact integrals of products of T6 shape functions."""
    corners = np.array([[0.1, 0.2], [1.3, -0.1], [0.4, 0.9]])
    X = np.vstack([corners, 0.5 * (corners + np.roll(corners, -1, axis=0))])
    b = body(X, np.arange(6)[None], "T6")
    area = 0.5 * cross(X[1] - X[0], X[2] - X[0])
    expected = np.array([
        [6, -1, -1, 0, -4, 0],
        [-1, 6, -1, 0, 0, -4],
        [-1, -1, 6, -4, 0, 0],
        [0, 0, -4, 32, 16, 16],
        [-4, 0, 0, 16, 32, 16],
        [0, -4, 0, 16, 16, 32],
    ]) * MATERIAL.density * area / 180
    np.testing.assert_allclose(b.mass.toarray()[::2, ::2], expected, rtol=1e-13, atol=1e-16)
    np.testing.assert_allclose(b.mass.toarray()[::2, 1::2], 0.0)


def test_boundary_loop_of_a_square():
    X, cells = square_mesh(3)
    loop = boundary_loop(cells, T3)
    on_boundary = np.flatnonzero((np.isclose(X, 0) | np.isclose(X, 1)).any(axis=1))
    assert sorted(loop) == sorted(on_boundary) and loop[0] == on_boundary.min()
    steps = np.linalg.norm(X[np.roll(loop, -1)] - X[loop], axis=1)
    np.testing.assert_allclose(steps, 1 / 3)
    assert boundary_integrals(X, loop, "T3")[0] == pytest.approx(1.0)  # counter-clockwise

    X6, cells6 = to_t6(X, cells)
    loop6 = boundary_loop(cells6, T6)
    np.testing.assert_array_equal(loop6[::2], loop)  # corners, with the midside nodes between
    np.testing.assert_allclose(X6[loop6[1::2]], 0.5 * (X[loop] + X[np.roll(loop, -1)]))


def test_boundary_loop_rejects_holes():
    X, cells = square_mesh(4)
    centre = (cells == np.argmin(np.linalg.norm(X - 0.5, axis=1))).any(axis=1)  # around (0.5, 0.5)
    with pytest.raises(ValueError, match="single closed loop"):
        boundary_loop(cells[~centre], T3)


@pytest.mark.parametrize("element", ["T3", "T6"])
def test_inverted_elements_are_detected(element):
    X3, cells = disk_mesh(2)
    x3 = X3.copy()
    x3[0] = [0.8, 0.1]  # push the centre node through its ring
    signed = cross(x3[cells[:, 1]] - x3[cells[:, 0]], x3[cells[:, 2]] - x3[cells[:, 0]])
    expected = np.flatnonzero(signed <= 0)
    assert expected.size > 0
    X, x = (X3, x3) if element == "T3" else (to_t6(X3, cells)[0], to_t6(x3, cells)[0])
    cells = cells if element == "T3" else to_t6(X3, cells)[1]
    b = body(X, cells, element, "mean_dilatation")
    np.testing.assert_array_equal(b.inverted_elements(x), expected)
    methods = (b.internal_force, b.internal_force_and_tangent, b.strain_energy, b.element_stresses)
    for method in methods:
        with pytest.raises(InvertedElementError) as info:
            method(x)
        np.testing.assert_array_equal(info.value.elements, expected)
    assert b.inverted_elements(X).size == 0


def test_invalid_meshes_are_rejected():
    X, cells = square_mesh(2)
    with pytest.raises(ValueError, match="reference Jacobian"):
        body(X, cells[:, [0, 2, 1]], "T3")
    with pytest.raises(ValueError, match="not used"):
        body(np.vstack([X, [[5.0, 5.0]]]), cells, "T3")
    with pytest.raises(ValueError, match=r"\(n_elem, 6\)"):
        body(X, cells, "T6")
    with pytest.raises(ValueError, match="volumetric"):
        body(X, cells, "T3", "f_bar")
    with pytest.raises(ValueError, match="shape"):
        body(X, cells, "T3").internal_force(X[:-1])
