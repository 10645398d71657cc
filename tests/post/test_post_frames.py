"""Reading an output folder: the data model, and OutputError on bad input."""

from __future__ import annotations

import meshio
import numpy as np
import pytest

from post.errors import OutputError
from post.frames import WALL_IDS, frame_path, iter_frames, read_contacts, read_frames_table

EMPTY_VTU = """<?xml version="1.0"?>
<VTKFile type="UnstructuredGrid" version="0.1" byte_order="LittleEndian">
  <UnstructuredGrid>
    <Piece NumberOfPoints="0" NumberOfCells="0">
      <Points><DataArray type="Float32" NumberOfComponents="3" format="ascii"></DataArray></Points>
      <Cells>
        <DataArray type="Int64" Name="connectivity" format="ascii"></DataArray>
        <DataArray type="Int64" Name="offsets" format="ascii"></DataArray>
        <DataArray type="UInt8" Name="types" format="ascii"></DataArray>
      </Cells>
    </Piece>
  </UnstructuredGrid>
</VTKFile>
"""


def test_frames_of_a_mixed_lattice(mixed_lattice):
    records = read_frames_table(mixed_lattice)
    assert [r.frame for r in records] == [0, 1, 2, 3]
    assert [r.equilibrated for r in records] == [True, False, True, True]
    assert records[3].pressure_applied == 0.1 and records[3].box == (0.0, 3.88, 0.0, 3.88)
    frame = next(iter_frames(mixed_lattice))
    bodies, contacts, walls = frame.bodies, frame.contacts, frame.walls
    assert bodies.n_bodies == 17
    assert np.flatnonzero(~bodies.rigid).tolist() == [5, 6]
    assert [(m.element, m.cells.shape) for m in bodies.meshes] == [("T6", (32, 6))]
    np.testing.assert_allclose(bodies.rigid_centres[bodies.rigid_ids == 16], [[1.0, 1.0]])
    assert bodies.radius[16] == 0.1 and bodies.radius[0] == 0.5
    # 24 disk-disk + 16 wall contacts, the 7 touching bodies 5 or 6 split in two, one rattler candidate
    assert len(contacts.fn) == 40 + 7 + 1
    assert contacts.force.shape == contacts.branch.shape == (48, 2) and contacts.segments.shape == (48, 2, 2)
    np.testing.assert_allclose(walls.position, [0, 4, 0, 4])
    np.testing.assert_allclose(walls.force / walls.length, 0.01)
    assert len(WALL_IDS) == len(walls.length)


def test_contacts_frame_without_cells_reads_as_no_contacts(tmp_path):
    path = tmp_path / "contacts_00000.vtu"
    path.write_text(EMPTY_VTU)
    contacts = read_contacts(path, n_bodies=3)
    assert contacts.fn.shape == (0,) and contacts.segments.shape == (0, 2, 2)


def _error(out_dir) -> OutputError:
    with pytest.raises(OutputError) as info:
        list(iter_frames(out_dir))
    return info.value


def test_missing_frames_csv(lattice):
    (lattice / "frames.csv").unlink()
    error = _error(lattice)
    assert error.file.endswith("frames.csv") and "frames.csv" in str(error) and "expected" in str(error)


def test_missing_column_in_frames_csv(lattice):
    path = lattice / "frames.csv"
    path.write_text(path.read_text().replace("pressure_applied", "pressure"))
    error = _error(lattice)
    assert error.field == "pressure_applied" and "frames.csv" in str(error)


def test_bad_value_in_frames_csv(lattice):
    path = lattice / "frames.csv"
    lines = path.read_text().splitlines()
    lines[1] = lines[1].replace(",1,", ",maybe,")
    path.write_text("\n".join(lines) + "\n")
    error = _error(lattice)
    assert error.field == "equilibrated" and "line 2" in str(error)


def test_missing_fn_field(lattice):
    path = frame_path(lattice, "contacts", 0)
    mesh = meshio.read(path)
    del mesh.cell_data["fn"]
    meshio.write(path, mesh)
    error = _error(lattice)
    assert "contacts_00000.vtu" in str(error) and error.field == "cell_data.fn" and "missing" in str(error)


def test_truncated_vtu(lattice):
    path = frame_path(lattice, "bodies", 1)
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    error = _error(lattice)
    assert "bodies_00001.vtu" in str(error) and "readable by meshio" in str(error)


def test_missing_vtu(lattice):
    frame_path(lattice, "walls", 1).unlink()
    assert "walls_00001.vtu" in str(_error(lattice))


def test_wrong_wall_ids(lattice):
    path = frame_path(lattice, "walls", 0)
    mesh = meshio.read(path)
    mesh.cell_data["wall"] = [np.array([-1, -2, -3, -3])]
    meshio.write(path, mesh)
    error = _error(lattice)
    assert "walls_00000.vtu" in str(error) and error.field == "cell_data.wall"


def test_vector_field_with_wrong_components(lattice):
    path = frame_path(lattice, "contacts", 0)
    mesh = meshio.read(path)
    mesh.cell_data["branch"] = [mesh.cell_data["branch"][0][:, :1]]
    meshio.write(path, mesh)
    error = _error(lattice)
    assert error.field == "cell_data.branch" and "2 or 3 components" in str(error)
