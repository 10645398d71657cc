"""Tests of pre/mesh.py: gmsh reference disk meshes (T3 / T6), placement, cache, I/O."""

import math
import threading
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

from pre.mesh import (
    DiskMesh,
    clear_mesh_cache,
    disk_mesh_resolution,
    reference_disk_mesh,
)

ELEMENTS = ("T3", "T6")


def polygon_signed_area(xy):
    x, y = xy[:, 0], xy[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


# ---- the default mesh (92 triangles: 57 T3 / 205 T6 nodes) ---------------------------------


@pytest.mark.parametrize("element, n_nodes, cell_width", [("T3", 57, 3), ("T6", 205, 6)])
def test_default_mesh_has_92_triangles(element, n_nodes, cell_width):
    m = reference_disk_mesh(element=element)
    assert m.element == element
    assert m.cells.shape == (92, cell_width)
    assert m.points.shape == (n_nodes, 2)
    assert m.cell_type == {"T3": "triangle", "T6": "triangle6"}[element]
    assert disk_mesh_resolution(92) == (20, pytest.approx(0.3))
    # every node is used, indices are contiguous
    assert np.array_equal(np.unique(m.cells), np.arange(m.n_nodes))


def test_default_arguments_and_cache():
    a = reference_disk_mesh()
    assert a is reference_disk_mesh(92, "T3")
    assert a is reference_disk_mesh(n_elements=92, element="T3")
    assert not a.points.flags.writeable and not a.cells.flags.writeable


def test_t3_and_t6_share_the_triangulation():
    m3, m6 = reference_disk_mesh(300, "T3"), reference_disk_mesh(300, "T6")
    assert m3.n_elements == m6.n_elements
    np.testing.assert_allclose(m6.points[m6.cells[:, :3]], m3.points[m3.cells])


# ---- element counts and quality ---------------------------------------------------------------


@pytest.mark.parametrize("target", [30, 300, 1000])
def test_element_count_within_10_percent(target):
    m = reference_disk_mesh(target)
    assert abs(m.n_elements - target) <= 0.10 * target


@pytest.mark.parametrize("target", [4, 5, 8, 12, 50, 150])
def test_small_and_odd_targets_are_close(target):
    m = reference_disk_mesh(target)
    assert abs(m.n_elements - target) <= max(2, 0.15 * target)


@pytest.mark.parametrize("element", ELEMENTS)
@pytest.mark.parametrize("target", [30, 92, 300, 1000])
def test_triangles_counter_clockwise(element, target):
    m = reference_disk_mesh(target, element)
    p = m.points[m.cells[:, :3]]
    d1, d2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    assert np.all(d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0] > 0)
    assert np.all(m.element_areas > 0)


@pytest.mark.parametrize("target", [30, 92, 300, 1000])
def test_elements_have_similar_sizes(target):
    # measured max/min area ratio: 2.0-2.9 for targets 30 ... 4000
    a = reference_disk_mesh(target).element_areas
    assert a.max() / a.min() < 4.0


def test_t6_midside_nodes_are_edge_midpoints_inside():
    m = reference_disk_mesh(92, "T6")
    c = m.cells
    boundary = set(m.boundary_nodes.tolist())
    for k, (i, j) in zip((3, 4, 5), ((0, 1), (1, 2), (2, 0))):
        mid = 0.5 * (m.points[c[:, i]] + m.points[c[:, j]])
        inside = np.array([n not in boundary for n in c[:, k]])
        np.testing.assert_allclose(m.points[c[inside, k]], mid[inside], atol=1e-12)


# ---- areas ---------------------------------------------------------------------------------


def test_t3_area_is_the_inscribed_polygon():
    for target in (30, 92, 300, 1000):
        m = reference_disk_mesh(target)
        n = len(m.boundary_nodes)
        assert m.area == pytest.approx(0.5 * n * math.sin(2 * math.pi / n), rel=1e-12)


def test_area_converges_to_pi():
    targets = (30, 92, 300, 1000)
    err3 = np.array([math.pi - reference_disk_mesh(t, "T3").area for t in targets])
    err6 = np.array([abs(math.pi - reference_disk_mesh(t, "T6").area) for t in targets])
    assert np.all(err3 > 0) and np.all(np.diff(err3) < 0)
    assert np.all(np.diff(err6) < 0)
    assert np.all(err6 < 0.05 * err3)
    # T3 error O(h^2) with h ~ 1 / sqrt(N): err * N roughly constant
    h2 = 1.0 / np.array([reference_disk_mesh(t).n_elements for t in targets])
    rate = np.polyfit(np.log(h2), np.log(err3), 1)[0]
    assert rate == pytest.approx(1.0, abs=0.15)  # measured 1.06
    # T6 with curved edges: at least O(h^3) (measured ~ O(h^4))
    rate6 = np.polyfit(np.log(h2), np.log(err6), 1)[0]
    assert rate6 > 1.5  # measured 2.1


def test_t6_area_default_mesh():
    assert abs(reference_disk_mesh(92, "T6").area - math.pi) < 1e-4
    assert abs(reference_disk_mesh(92, "T3").area - math.pi) > 0.05


# ---- boundary ------------------------------------------------------------------------------


@pytest.mark.parametrize("element", ELEMENTS)
@pytest.mark.parametrize("target", [30, 92, 1000])
def test_boundary_nodes_on_unit_circle_ccw_loop(element, target):
    m = reference_disk_mesh(target, element)
    b = m.boundary_nodes
    assert len(np.unique(b)) == len(b)
    xy = m.points[b]
    np.testing.assert_allclose(np.hypot(xy[:, 0], xy[:, 1]), 1.0, atol=1e-12)
    # CCW: angles increase monotonically by one full turn
    dtheta = np.diff(np.unwrap(np.arctan2(xy[:, 1], xy[:, 0])))
    assert np.all(dtheta > 0)
    assert polygon_signed_area(xy) > 0
    # every node not in the loop is strictly inside
    interior = np.setdiff1d(np.arange(m.n_nodes), b)
    assert np.all(np.hypot(*m.points[interior].T) < 1 - 1e-9)
    # T3 default: 20 boundary nodes; T6: plus 20 midside nodes
    if target == 92:
        assert len(b) == (20 if element == "T3" else 40)


# ---- boundary-graded meshes ------------------------------------------------------------------


@pytest.mark.parametrize("segments", [120, 240])
def test_graded_mesh_boundary_and_sizes(segments):
    from pre.mesh import GRADING

    m = reference_disk_mesh(300, "T6", boundary_segments=segments)
    uniform = reference_disk_mesh(300, "T6")
    b = m.boundary_nodes
    assert len(b) == 2 * segments  # vertices and midside nodes, all on the circle
    np.testing.assert_allclose(np.hypot(*m.points[b].T), 1.0, atol=1e-12)
    assert m.n_elements > uniform.n_elements
    assert abs(m.area - math.pi) < abs(uniform.area - math.pi)
    # element size (equilateral-equivalent edge) against the distance to the circle: the size
    # field h(d) = 2 pi / segments + GRADING d, capped by the interior size (gmsh meets a size
    # field within a factor of about 1.5)
    corners = m.points[m.cells[:, :3]]
    d = 1.0 - np.hypot(*corners.mean(axis=1).T)
    size = np.sqrt(4.0 * m.element_areas / math.sqrt(3.0))
    target = np.minimum(2 * math.pi / segments + GRADING * d, disk_mesh_resolution(300)[1])
    ratio = size / target
    assert 0.5 < np.median(ratio) < 1.5
    assert np.all(ratio < 2.5) and np.all(ratio > 0.3)


def test_graded_mesh_needs_more_segments_than_uniform():
    n_uniform = disk_mesh_resolution(300)[0]
    with pytest.raises(ValueError, match="boundary_segments"):
        reference_disk_mesh(300, "T6", boundary_segments=n_uniform)
    with pytest.raises(ValueError, match="boundary_segments"):
        reference_disk_mesh(300, "T6", boundary_segments=200.5)


# ---- placement ------------------------------------------------------------------------------


@pytest.mark.parametrize("element", ELEMENTS)
def test_placed_scales_area_and_translates(element):
    ref = reference_disk_mesh(92, element)
    centre, r = np.array([3.5, -1.25]), 0.37
    m = ref.placed(centre, r)
    assert m.element == element and m.n_elements == ref.n_elements
    assert m.area == pytest.approx(ref.area * r**2, rel=1e-12)
    np.testing.assert_allclose(np.hypot(*(m.points[m.boundary_nodes] - centre).T), r, atol=1e-12)
    np.testing.assert_array_equal(m.boundary_nodes, ref.boundary_nodes)
    assert ref.points[0, 0] == pytest.approx(1.0)  # the reference is untouched
    assert reference_disk_mesh(92, element) is ref  # and still the cached one


@pytest.mark.parametrize("centre, radius", [((0, 0), 0.0), ((0, 0), -1.0), ((0, 0, 0), 1.0), ((np.nan, 0), 1.0)])
def test_placed_rejects_bad_input(centre, radius):
    with pytest.raises(ValueError, match="placed"):
        reference_disk_mesh().placed(centre, radius)


# ---- I/O -------------------------------------------------------------------------------------


@pytest.mark.parametrize("element", ELEMENTS)
@pytest.mark.parametrize("suffix", [".msh", ".vtu"])
def test_meshio_round_trip(tmp_path, element, suffix, capfd):
    m = reference_disk_mesh(92, element).placed((1.0, 2.0), 0.5)
    path = tmp_path / f"disk{suffix}"
    m.write(path)
    back = DiskMesh.read(path)
    assert back.element == element
    np.testing.assert_allclose(back.points, m.points, atol=1e-12)
    np.testing.assert_array_equal(back.cells, m.cells)
    assert back.area == pytest.approx(m.area, rel=1e-12)
    out, err = capfd.readouterr()
    assert out == "" and "Warning" not in err  # meshio stays quiet


def test_meshio_readable_by_plain_meshio(tmp_path):
    import meshio

    m = reference_disk_mesh(92, "T6")
    m.write(tmp_path / "d.vtu")
    raw = meshio.read(tmp_path / "d.vtu")
    assert raw.cells[0].type == "triangle6" and raw.cells[0].data.shape == (92, 6)


def test_io_rejects_bad_extension(tmp_path):
    with pytest.raises(ValueError, match=r"\.msh or \.vtu"):
        reference_disk_mesh().write(tmp_path / "d.stl")
    with pytest.raises(ValueError, match=r"\.msh or \.vtu"):
        DiskMesh.read(tmp_path / "d.stl")


# ---- errors ----------------------------------------------------------------------------------


@pytest.mark.parametrize("n", [3, 0, -5, 2.5, "92", None, True])
def test_bad_n_elements(n):
    with pytest.raises(ValueError, match=r"n_elements.*>= 4"):
        reference_disk_mesh(n)


@pytest.mark.parametrize("element", ["T4", "t3", "Q4", "", None])
def test_bad_element(element):
    with pytest.raises(ValueError, match=r"element.*'T3'.*'T6'"):
        reference_disk_mesh(92, element)


def test_numpy_integer_target_accepted():
    assert reference_disk_mesh(np.int64(92)) is reference_disk_mesh(92)


def test_diskmesh_validates_shapes():
    with pytest.raises(ValueError, match="cells"):
        DiskMesh(points=np.zeros((3, 2)), cells=np.array([[0, 1, 2]]), element="T6")
    with pytest.raises(ValueError, match="points"):
        DiskMesh(points=np.zeros((3, 3)), cells=np.array([[0, 1, 2]]), element="T3")
    with pytest.raises(ValueError, match="cells"):
        DiskMesh(points=np.zeros((3, 2)), cells=np.array([[0, 1, 3]]), element="T3")


# ---- threads ---------------------------------------------------------------------------------


def test_concurrent_calls_from_threads():
    jobs = [(200, "T3"), (210, "T6"), (220, "T3"), (230, "T6"), (200, "T6"), (210, "T3")]
    clear_mesh_cache()
    barrier = threading.Barrier(2)

    def work(job):
        if job in jobs[:2]:
            barrier.wait(timeout=10)  # make the first two start together
        m = reference_disk_mesh(*job)
        return m.n_elements, m.points.copy(), m.cells.copy()

    with ThreadPoolExecutor(max_workers=2) as pool:
        results = list(pool.map(work, jobs))
    clear_mesh_cache()
    for job, (ne, pts, cells) in zip(jobs, results):
        seq = reference_disk_mesh(*job)
        assert ne == seq.n_elements
        np.testing.assert_array_equal(cells, seq.cells)
        np.testing.assert_allclose(pts, seq.points)
