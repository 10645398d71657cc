"""The bodies file (scene and frames): written zlib-compressed, read back exactly."""

from __future__ import annotations

import numpy as np

from compute.bodies_io import write_bodies


def test_bodies_file_is_compressed_and_reads_back_exactly(tmp_path):
    """Two rigid disks and one T3 body with float fields of no pattern (which compress poorly):
    the file declares the zlib compressor, and every position, radius and field reads back bit
    for bit."""
    rng = np.random.default_rng(3)
    points = rng.random((4, 2)) + 5.0
    cells = np.array([[0, 1, 2], [0, 2, 3]])
    centres, radii = np.array([[1.0, 1.0], [3.0, 1.0], [5.5, 5.5]]), np.array([0.5, 0.7, 0.6])
    velocity = {"rigid": rng.random((2, 3)), "deformable": {2: rng.random((4, 3))}}
    path = tmp_path / "bodies.vtu"
    write_bodies(path, centres, radii, np.array([0, 0, 1]), {2: (points, cells, "T3")}, point_data={"velocity": velocity})
    assert 'compressor="vtkZLibDataCompressor"' in path.read_text(errors="replace")[:2000]
    import meshio

    mesh = meshio.read(path)
    np.testing.assert_array_equal(mesh.points[:2, :2], centres[:2])
    np.testing.assert_array_equal(mesh.points[2:, :2], points)
    np.testing.assert_array_equal(mesh.point_data["velocity"], np.vstack([velocity["rigid"], velocity["deformable"][2]]))
