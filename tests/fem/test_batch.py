"""BodyBatch (all bodies of a group at once) against FEBody body by body, finite differences,
closed-form rigid-body quantities, inverted elements, inactive bodies and invalid meshes."""

import numpy as np
import pytest

from compute.fem import FEBody, NeoHookean
from compute.fem.batch import BodyBatch
from pre.mesh import reference_disk_mesh

from .meshes import disk_mesh, to_t6

MATERIAL = NeoHookean(young=2.0, poisson=0.45, density=1.7)
CASES = [("T3", "standard"), ("T6", "mean_dilatation"), ("T6", "standard")]
RADII = np.array([0.5, 1.0, 1.3, 0.8])
CENTRES = np.array([[0.0, 0.0], [3.0, -1.0], [-2.5, 4.0], [10.0, 7.5]])


def unit_disk(element: str, kind: str) -> tuple[np.ndarray, np.ndarray]:
    """Unit disk centred at the origin: "hand" (2-ring hexagonal disk, 24 elements) or "gmsh"
    (the 92-element reference mesh); T6 boundary midside nodes on the circle."""
    if kind == "gmsh":
        mesh = reference_disk_mesh(92, element)
        return np.array(mesh.points), np.array(mesh.cells)
    X, cells = disk_mesh(2)
    return (X, cells) if element == "T3" else to_t6(X, cells, circle_radius=1.0)


def references(X0: np.ndarray) -> np.ndarray:
    """(B, n, 2) reference positions: the unit mesh scaled by RADII, moved to CENTRES."""
    return RADII[:, None, None] * X0 + CENTRES[:, None, :]


def deformed(X: np.ndarray, seed: int = 0) -> np.ndarray:
    """Random smooth deformations (rotation, small compression or shear, smooth waves) of every
    body, (B, n, 2); J stays well positive."""
    rng = np.random.default_rng(seed)
    x = np.empty_like(X)
    for b in range(X.shape[0]):
        c, r = CENTRES[b], RADII[b]
        angle = rng.uniform(-np.pi, np.pi)
        R = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
        F = R @ (np.diag(rng.uniform(0.85, 1.0, 2)) + rng.uniform(-0.1, 0.1, (2, 2)))
        Y = (X[b] - c) / r  # unit-disk coordinates
        waves = 0.04 * np.column_stack(
            [np.sin(rng.uniform(1, 3) * Y[:, 1] + rng.uniform(0, 6)),
             np.cos(rng.uniform(1, 3) * Y[:, 0] + rng.uniform(0, 6))]
        )
        x[b] = c + rng.uniform(-0.3, 0.3, 2) + r * ((Y + waves) @ F.T)
    return x


def close(a, b, rtol=1e-12):
    """|a - b| <= rtol max|b| (relative to the array's scale)."""
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape
    assert np.abs(a - b).max() <= rtol * np.abs(b).max(), np.abs(a - b).max() / np.abs(b).max()


def build(element, volumetric, kind):
    X0, cells = unit_disk(element, kind)
    X = references(X0)
    batch = BodyBatch(X, cells, element, MATERIAL, volumetric)
    bodies = [FEBody(X[b], cells, element, MATERIAL, volumetric) for b in range(batch.B)]
    return batch, bodies


@pytest.mark.parametrize("kind", ["hand", "gmsh"])
@pytest.mark.parametrize("element,volumetric", CASES)
def test_matches_febody(element, volumetric, kind):
    batch, bodies = build(element, volumetric, kind)
    B, nnz = batch.B, batch.indices.size
    x = deformed(batch.X, seed=1)
    assert batch.n_dof == 2 * batch.n_nodes == bodies[0].n_dof
    np.testing.assert_array_equal(batch.indptr, bodies[0].mass.indptr)
    np.testing.assert_array_equal(batch.indices, bodies[0].mass.indices)
    np.testing.assert_array_equal(batch.boundary, bodies[0].boundary)

    f, kdata = np.empty((B, batch.n_dof)), np.empty((B, nnz))
    ok = batch.internal_force_and_tangent(x, np.ones(B, bool), f, kdata)
    assert ok.dtype == bool and ok.all()
    f_only = np.empty((B, batch.n_dof))
    assert batch.internal_force(x, np.ones(B, bool), f_only).all()
    vg = np.empty((B, nnz))
    batch.volumetric_geometric(x, np.ones(B, bool), vg)
    J, areas, centroids = batch.jacobians(x), batch.areas(x), batch.centroids(x)
    stresses, energy = batch.element_stresses(x), batch.strain_energy(x)
    assert J.shape == (B, batch.cells.shape[0], batch.element.stiffness_rule.weights.size)
    assert stresses.cauchy.shape == (B, batch.cells.shape[0], 3, 3)

    for b, body in enumerate(bodies):
        f_b, k_b = _force_and_tangent_values(body, x[b])
        close(f[b], f_b)
        close(f_only[b], f_b)
        close(kdata[b], k_b)
        close(vg[b], body.volumetric_geometric_data(x[b]))
        close(J[b], body.jacobians(x[b]))
        close(areas[b], body.area(x[b]))
        close(centroids[b], body.centroid(x[b]))
        s_b = body.element_stresses(x[b])
        for got, want in zip(stresses, s_b):
            close(got[b], want)
        close(energy[b], body.strain_energy(x[b]))
        close(batch.mass_data[b], body.mass.data)
        close(batch.reference_areas[b], body.reference_areas)
        np.testing.assert_array_equal(batch.X[b], body.X)


@pytest.mark.parametrize("element,volumetric", CASES)
def test_mass_and_kinetic_energy(element, volumetric):
    batch, bodies = build(element, volumetric, "hand")
    rng = np.random.default_rng(2)
    v = rng.normal(size=(batch.B, batch.n_dof))
    Mv = batch.mass_times(v)
    out = np.full_like(v, np.nan)
    assert batch.mass_times(v, out) is out
    for b, body in enumerate(bodies):
        close(Mv[b], body.mass @ v[b])
        close(out[b], body.mass @ v[b])
    want = sum(0.5 * v[b] @ (body.mass @ v[b]) for b, body in enumerate(bodies))
    assert batch.kinetic_energy(v) == pytest.approx(want, rel=1e-12)

    # closed forms: a rigid translation u of body b has kinetic energy rho a_b |u|^2 / 2,
    # a_b = r_b^2 times the unit mesh's area (pi for the curved T6 disk up to the mesh error)
    u = np.array([0.3, -1.2])
    v_rigid = np.tile(u, (batch.B, batch.n_nodes)).reshape(batch.B, -1)
    unit_area = batch.reference_areas[1].sum()  # body 1 has radius 1
    a = RADII**2 * unit_area
    np.testing.assert_allclose(batch.reference_areas.sum(axis=1), a, rtol=1e-13)
    assert batch.kinetic_energy(v_rigid) == pytest.approx(0.5 * MATERIAL.density * a.sum() * u @ u,
                                                          rel=1e-13)
    if element == "T6":
        assert unit_area == pytest.approx(np.pi, rel=1e-2)


@pytest.mark.parametrize("element,volumetric", CASES)
def test_rigid_placement(element, volumetric):
    """At a rigid motion of the reference configuration: zero force, energy and stresses,
    J = 1, areas unchanged, centroids at the (moved) disk centres (symmetric mesh)."""
    batch, _ = build(element, volumetric, "hand")
    angle = 0.7
    R = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    shift = np.array([1.5, -0.5])
    x = (batch.X - CENTRES[:, None, :]) @ R.T + CENTRES[:, None, :] + shift
    f = np.empty((batch.B, batch.n_dof))
    assert batch.internal_force(x, np.ones(batch.B, bool), f).all()
    scale = MATERIAL.young * RADII[:, None]  # force scale per body
    assert np.abs(f / scale).max() < 1e-12
    np.testing.assert_allclose(batch.jacobians(x), 1.0, rtol=1e-12)
    np.testing.assert_allclose(batch.strain_energy(x), 0.0, atol=1e-13)
    assert np.abs(batch.element_stresses(x).cauchy).max() < 1e-12 * MATERIAL.young
    np.testing.assert_allclose(batch.areas(x), batch.reference_areas.sum(axis=1), rtol=1e-12)
    np.testing.assert_allclose(batch.centroids(x), CENTRES + shift, atol=1e-12)


@pytest.mark.parametrize("element,volumetric", CASES)
def test_finite_differences(element, volumetric):
    """f = dE/dx and K_t = df/dx on body 2 of a batch (only that body active)."""
    batch, _ = build(element, volumetric, "hand")
    B, n_dof, target = batch.B, batch.n_dof, 2
    x = deformed(batch.X, seed=3)
    active = np.arange(B) == target
    f = np.empty((B, n_dof))
    kdata = np.empty((B, batch.indices.size))
    assert batch.internal_force_and_tangent(x, active, f, kdata).all()
    K = np.zeros((n_dof, n_dof))
    rows = np.repeat(np.arange(n_dof), np.diff(batch.indptr))
    K[rows, batch.indices] = kdata[target]

    eps = 1e-6 * RADII[target]
    grad = np.empty(n_dof)
    K_fd = np.empty((n_dof, n_dof))
    f_plus, f_minus = np.empty((B, n_dof)), np.empty((B, n_dof))
    for j in range(n_dof):
        step = np.zeros((B, n_dof))
        step[target, j] = eps
        step = step.reshape(x.shape)
        grad[j] = (batch.strain_energy(x + step)[target]
                   - batch.strain_energy(x - step)[target]) / (2 * eps)
        batch.internal_force(x + step, active, f_plus)
        batch.internal_force(x - step, active, f_minus)
        K_fd[:, j] = (f_plus[target] - f_minus[target]) / (2 * eps)
    assert np.abs(f[target] - grad).max() < 1e-6 * np.abs(f[target]).max()
    assert np.abs(K - K_fd).max() < 1e-6 * np.abs(K).max()
    assert np.abs(K - K.T).max() <= 1e-13 * np.abs(K).max()


@pytest.mark.parametrize("element,volumetric", CASES)
def test_inverted_and_inactive_bodies(element, volumetric):
    batch, bodies = build(element, volumetric, "hand")
    B, nnz = batch.B, batch.indices.size
    x = deformed(batch.X, seed=4)
    for b in (1, 3):  # push the centre node (node 0) of bodies 1 and 3 out of the disk
        x[b, 0] = CENTRES[b] + [2.5 * RADII[b], 0.0]
        assert bodies[b].inverted_elements(x[b]).size > 0
    active = np.array([True, True, False, False])  # body 3 inverted but inactive
    f = np.full((B, batch.n_dof), np.nan)
    kdata = np.full((B, nnz), np.nan)
    ok = batch.internal_force_and_tangent(x, active, f, kdata)
    np.testing.assert_array_equal(ok, [True, False, True, True])
    f_b, k_b = _force_and_tangent_values(bodies[0], x[0])
    close(f[0], f_b)
    close(kdata[0], k_b)
    assert np.isnan(f[2:]).all() and np.isnan(kdata[2:]).all()  # inactive: untouched

    f_only = np.full((B, batch.n_dof), np.nan)
    np.testing.assert_array_equal(batch.internal_force(x, active, f_only), ok)
    close(f_only[0], f_b)
    assert np.isnan(f_only[2:]).all()
    vg = np.full((B, nnz), 7.0)
    batch.volumetric_geometric(x, np.array([True, False, False, True]), vg)
    close(vg[0], bodies[0].volumetric_geometric_data(x[0]))
    assert (vg[1:3] == 7.0).all()

    # diagnostics: no exception, NaN / J <= 0 exactly where FEBody finds inverted elements
    J = batch.jacobians(x)
    energy = batch.strain_energy(x)
    stresses = batch.element_stresses(x)
    for b, body in enumerate(bodies):
        bad = body.inverted_elements(x[b])
        np.testing.assert_array_equal(np.flatnonzero(~(J[b] > 0).all(axis=1)), bad)
        assert np.isnan(energy[b]) == (bad.size > 0)
        np.testing.assert_array_equal(np.flatnonzero(np.isnan(stresses.pressure[b])), bad)


def test_invalid_meshes_name_the_body():
    X0, cells = unit_disk("T6", "hand")
    X = references(X0)
    BodyBatch(X, cells, "T6", MATERIAL, "standard")
    mirrored = X.copy()
    mirrored[2, :, 0] *= -1.0  # body 2 clockwise
    with pytest.raises(ValueError, match="body 2:"):
        BodyBatch(mirrored, cells, "T6", MATERIAL, "standard")
    nan = X.copy()
    nan[1, 5, 1] = np.nan
    with pytest.raises(ValueError, match="body 1:"):
        BodyBatch(nan, cells, "T6", MATERIAL, "standard")
    with pytest.raises(ValueError, match="volumetric"):
        BodyBatch(X, cells, "T6", MATERIAL, "selective")
    with pytest.raises(ValueError, match="cells"):
        BodyBatch(X, cells[:, :3], "T6", MATERIAL, "standard")
    with pytest.raises(ValueError, match="X must be"):
        BodyBatch(X[0], cells, "T6", MATERIAL, "standard")
    batch = BodyBatch(X, cells, "T6", MATERIAL, "standard")
    with pytest.raises(ValueError, match="kdata"):
        batch.internal_force_and_tangent(
            X, np.ones(batch.B, bool), np.empty((batch.B, batch.n_dof)),
            np.empty((batch.B, batch.indices.size), dtype=np.float32),
        )
    with pytest.raises(ValueError, match="positions"):
        batch.jacobians(X[:2])


def _force_and_tangent_values(body, x):
    """f_int (2n,) and the values (nnz,) of K_t in the body's CSR pattern."""
    f, k = body.internal_force_and_tangent(x)
    return f, k.data


def test_mass_scaling_is_the_materials_mass_times_the_factor():
    """BodyBatch.scale_mass: the mass matrices are the material's times the factor, set from the
    material's each time (bit for bit the same whatever factor came before, 1 gives them back);
    mass_times(material=True) keeps the material's mass (weights)."""
    X, cells = disk_mesh(2)
    batch = BodyBatch(np.stack([X, X + 3.0]), cells, "T3", NeoHookean(1.0, 0.3, 2.0), "standard")
    material = batch.mass_data.copy()
    v = np.random.default_rng(3).normal(size=(2, batch.n_dof))
    batch.scale_mass(7.0)
    direct = batch.mass_data.copy()
    np.testing.assert_allclose(batch.mass_times(v), 7.0 * batch.mass_times(v, material=True), rtol=1e-13)
    batch.scale_mass(3.0)
    batch.scale_mass(7.0)
    assert np.array_equal(batch.mass_data, direct)
    batch.scale_mass(1.0)
    assert np.array_equal(batch.mass_data, material) and batch.mass_scale == 1.0
