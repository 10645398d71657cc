"""Every malformed scene stops with a SceneError naming the file, the field and what was expected."""

import re
from pathlib import Path

import numpy as np
import pytest

from compute.errors import SceneError
from compute.scene import read_scene
from pre.scene import default_parameters, write_scene

CENTRES = [(1.0, 1.0), (2.5, 1.0), (1.0, 2.5)]
RADII = [0.5, 0.5, 0.5]


@pytest.fixture
def scene(tmp_path) -> Path:
    write_scene(tmp_path / "scene", default_parameters((0, 4, 0, 4), 0.2, 1.0, [1.0]), CENTRES, RADII,
                ["rigid"] * 3)
    read_scene(tmp_path / "scene")  # the unmodified scene is valid
    return tmp_path / "scene"


def _edit_toml(scene: Path, old: str, new: str) -> None:
    f = scene / "scene.toml"
    text = f.read_text()
    assert re.search(old, text, flags=re.M), old
    f.write_text(re.sub(old, new, text, count=1, flags=re.M))


def _expect(scene: Path, file: str, field: str, expected: str) -> None:
    with pytest.raises(SceneError) as err:
        read_scene(scene)
    msg = str(err.value)
    assert file in msg and f"'{field}'" in msg and expected in msg, msg


def test_missing_field(scene):
    _edit_toml(scene, r"^time_step = .*$", "")
    _expect(scene, "scene.toml", "solver.time_step", "a finite number (time step h) (missing)")


def test_mistyped_field(scene):
    _edit_toml(scene, r"^time_step = .*$", 'time_step = "fast"')
    _expect(scene, "scene.toml", "solver.time_step", "a finite number")


def test_out_of_range_field(scene):
    _edit_toml(scene, r"^theta = .*$", "theta = 0.2")
    _expect(scene, "scene.toml", "solver.theta", "in [0.5, 1]")


def test_unknown_contact_solver(scene):
    _edit_toml(scene, r'^contact = "auto"$', 'contact = "lemke"')
    _expect(scene, "scene.toml", "solver.contact", "one of 'auto', 'nlgs', 'block'")


def test_the_frictionless_solver_is_refused_for_friction(scene):
    """'mprgp' solves frictionless contact only: a scene with friction (this one, 0.2) is refused
    when read, not at its first contact solve."""
    _edit_toml(scene, r'^contact = "auto"$', 'contact = "mprgp"')
    _expect(scene, "scene.toml", "solver.contact", "frictionless contact only")
    _edit_toml(scene, r"^friction = 0.2$", "friction = 0.0")
    read_scene(scene)


def test_unknown_material_kind(scene):
    _edit_toml(scene, r'^kind = "rigid"$', 'kind = "plasticine"')
    _expect(scene, "scene.toml", "materials.rigid.kind", "one of 'rigid', 'neo_hookean'")


def test_unknown_material_name_in_bodies(scene):
    _edit_toml(scene, r'^materials = \[\s*"rigid",\s*\]$', 'materials = ["steel"]')
    _expect(scene, "scene.toml", "bodies.materials", "names defined in [materials]")


def test_unknown_law(scene):
    _edit_toml(scene, r'^law = "coulomb"$', 'law = "mohr"')
    _expect(scene, "scene.toml", "interactions[0].law", "one of 'coulomb', 'frictionless'")


def test_missing_interaction(scene):
    text = (scene / "scene.toml").read_text()
    start = text.index("[[interactions]]")
    end = text.index("\n[", start) + 1
    (scene / "scene.toml").write_text(text[:start] + text[end:])
    _expect(scene, "scene.toml", "interactions", "a non-empty array of tables")


def test_toml_syntax(scene):
    (scene / "scene.toml").write_text((scene / "scene.toml").read_text() + "\nthis is not toml\n")
    _expect(scene, "scene.toml", "<syntax>", "valid TOML")


def _rewrite_bodies(scene: Path, centres, radii):
    write_scene(scene.parent / "tmp", default_parameters((0, 4, 0, 4), 0.2, 1.0, [1.0]), centres, radii,
                ["rigid"] * len(radii))
    (scene.parent / "tmp" / "bodies.vtu").replace(scene / "bodies.vtu")


def test_negative_radius(scene):
    _rewrite_bodies(scene, CENTRES, [0.5, -0.5, 0.5])
    _expect(scene, "bodies.vtu", "cell_data.radius", "positive radii in [1e-12, 1e+12]")


def test_overlapping_bodies(scene):
    _rewrite_bodies(scene, [(1.0, 1.0), (1.5, 1.0), (1.0, 2.5)], RADII)
    _expect(scene, "bodies.vtu", "points/radius", "non-overlapping bodies")


def test_body_outside_walls(scene):
    _rewrite_bodies(scene, [(1.0, 1.0), (3.8, 1.0), (1.0, 2.5)], RADII)
    _expect(scene, "bodies.vtu", "radius/points of body 1", "inside the walls' box")


def test_truncated_bodies_file(scene):
    f = scene / "bodies.vtu"
    f.write_bytes(f.read_bytes()[: len(f.read_bytes()) // 2])
    _expect(scene, "bodies.vtu", "<file>", "a complete VTU file readable by meshio")


def test_missing_bodies_field(scene):
    import meshio

    f = scene / "bodies.vtu"
    mesh = meshio.read(f, file_format="vtu")
    del mesh.cell_data["radius"]
    meshio.write(f, mesh, file_format="vtu")
    _expect(scene, "bodies.vtu", "cell_data.radius", "a cell array on every cell block")


def test_a_poisson_ratio_the_elements_lock_at_is_refused(tmp_path):
    """0.4999999 was inside the range, and the single particle failed at stage 1 with it."""
    from pre.single_particle import write

    scene = write(tmp_path / "scene", element="T3", elements=40, pressures=[1e-3])
    _edit_toml(scene, r"^poisson = .*$", "poisson = 0.4999999")
    _expect(scene, "scene.toml", "materials.soft.poisson", "in (-1, 0.499999]")


def test_pressures_beyond_what_the_elements_handle_are_refused(tmp_path):
    """young = 1e-12 under P = 1e-3 (P/E = 1e9) failed at step 2 inverting an element."""
    from pre.single_particle import write

    scene = write(tmp_path / "scene", element="T3", elements=40, pressures=[1e-3])
    _edit_toml(scene, r"^young = .*$", "young = 1e-12")
    _expect(scene, "scene.toml", "loading.pressures", "up to 5 x the young modulus of material 'soft'")


def test_points_off_the_plane_are_refused(scene):
    """A 3D point is not flattened silently: the toolkit is 2D."""
    import meshio

    f = scene / "bodies.vtu"
    mesh = meshio.read(f, file_format="vtu")
    mesh.points[1, 2] = 0.25
    meshio.write(f, mesh, file_format="vtu")
    _expect(scene, "bodies.vtu", "points", "points in the plane z = 0")


def test_a_bodies_file_outside_the_scene_folder_needs_the_flag(scene, tmp_path, capsys):
    from compute.__main__ import main

    elsewhere = tmp_path / "x"
    elsewhere.mkdir()
    (scene / "bodies.vtu").replace(elsewhere / "bodies.vtu")
    _edit_toml(scene, r'^file = "bodies.vtu"$', 'file = "../x/bodies.vtu"')
    _expect(scene, "scene.toml", "bodies.file", "a file inside the scene folder")
    assert main([str(scene), "--out", str(tmp_path / "out")]) == 2
    assert "--bodies-outside-scene" in capsys.readouterr().err and not (tmp_path / "out").exists()
    assert len(read_scene(scene, bodies_outside=True).radius) == 3  # asked for explicitly: read


def test_cli_reports_the_error(scene, tmp_path, capsys):
    from compute.__main__ import main

    _edit_toml(scene, r"^time_step = .*$", "time_step = -1.0")
    assert main([str(scene), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "scene.toml" in err and "solver.time_step" in err and "in [1e-12, 1e+12]" in err


# --- every way a scene went wrong before the scene schema, one test each ------------------------
@pytest.mark.parametrize("old, new, field, expected", [
    (r"^time_step = .*$", "time_step = 1e300", "solver.time_step", "in [1e-12, 1e+12]"),
    (r"^time_step = .*$", "time_step = 1e-300", "solver.time_step", "in [1e-12, 1e+12]"),
    (r"^pressures = \[\s*1.0,\s*\]$", "pressures = [1e300]", "loading.pressures[0]", "in [1e-12, 1e+12]"),
    (r"^pressures = \[\s*1.0,\s*\]$", "pressures = [inf]", "loading.pressures[0]", "a finite number"),
    (r"^gravity = \[[^\]]*\]", "gravity = [nan, 0.0]", "loading.gravity[0]", "a finite number"),
    (r"^gravity = \[[^\]]*\]", "gravity = [0.0, -inf]", "loading.gravity[1]", "a finite number"),
    (r"^gravity = \[[^\]]*\]", "gravity = [true, 0.0]", "loading.gravity[0]", "a finite number"),
    (r"^density = .*$", "density = 1e300", "materials.rigid.density", "in [1e-12, 1e+12]"),
    (r"^mass = .*$", "mass = 1e300", "walls.mass", "in [1e-12, 1e+12]"),
    (r"^force_tolerance = ", "force_tolerence = ", "loading.force_tolerence", "did you mean force_tolerance?"),
    (r"^damping_inertial_number = ", "damping_inertial_numbr = ", "walls.damping_inertial_numbr",
     "did you mean damping_inertial_number?"),
    (r"^newton_max_iterations = ", "newton_max_iteration = ", "solver.newton_max_iteration",
     "did you mean newton_max_iterations?"),
    (r"^\[output\]$", "[outputs]\nframes = \"stages\"\n\n[output]", "outputs", "did you mean output?"),
    (r"^skin = (.*)$", r"skin = \1\nskim = 0.2", "solver.skim", "did you mean skin?"),
    (r"^fixed = false$", "fixed = 0", "materials.rigid.fixed", "true or false"),
    (r"^check_every = .*$", "check_every = 20.5", "loading.check_every", "an integer"),
])
def test_scene_value_is_refused_with_its_field(scene, old, new, field, expected):
    _edit_toml(scene, old, new)
    _expect(scene, "scene.toml", field, expected)


def test_unreadable_scene_file(scene, monkeypatch):
    real = Path.read_bytes

    def denied(self, *a, **k):
        if self.name == "scene.toml":
            raise PermissionError(13, "Permission denied", str(self))
        return real(self, *a, **k)

    monkeypatch.setattr(Path, "read_bytes", denied)
    _expect(scene, "scene.toml", "<file>", "a file this user can read")


def test_vertex_cell_past_the_points(scene):
    import meshio

    f = scene / "bodies.vtu"
    mesh = meshio.read(f, file_format="vtu")
    mesh.cells[0].data[-1, 0] = len(mesh.points) + 5
    meshio.write(f, mesh, file_format="vtu")
    _expect(scene, "bodies.vtu", "cells (vertex)", "point indices in 0..2")


def test_a_bad_scene_writes_nothing(scene, tmp_path):
    from compute.__main__ import main

    _edit_toml(scene, r"^time_step = .*$", "time_step = 1e300")
    assert main([str(scene), "--out", str(tmp_path / "out")]) == 2
    assert not (tmp_path / "out").exists()


def test_out_is_an_existing_file(scene, tmp_path, capsys):
    from compute.__main__ import main

    (tmp_path / "out").write_text("not a folder")
    assert main([str(scene), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "out: field '--out': expected an output folder, got 'an existing file'" in err


def test_out_in_a_folder_that_cannot_be_written(scene, tmp_path, capsys, monkeypatch):
    from compute.__main__ import main

    def denied(self, *a, **k):
        raise PermissionError(13, "Permission denied", str(self))

    monkeypatch.setattr(Path, "mkdir", denied)  # the test may run as root, which chmod does not stop
    assert main([str(scene), "--out", str(tmp_path / "ro" / "out")]) == 2
    err = capsys.readouterr().err
    assert "field '--out': expected a folder this user can create and write in" in err and "Permission denied" in err


def test_an_overflow_mid_run_stops_with_a_diagnosis(scene, tmp_path, monkeypatch):
    from compute.errors import SimulationError
    from compute.run import Run
    from compute.stepping.moreau_jean import Stepper

    real = Stepper.step

    def overflowing(self, state, *a):
        if state.step == 7:
            raise OverflowError("cannot convert float infinity to integer")
        return real(self, state, *a)

    monkeypatch.setattr(Stepper, "step", overflowing)
    with pytest.raises(SimulationError, match="step 8: numerical overflow"):
        Run(scene, tmp_path / "out", log=lambda m: None).execute()
    assert "numerical overflow" in (tmp_path / "out" / "FAILED").read_text()
    steps = np.loadtxt(tmp_path / "out" / "history.csv", delimiter=",", skiprows=1, usecols=1)
    assert np.array_equal(steps, np.arange(1, 8))  # what was computed before is kept


@pytest.mark.parametrize("elements", [92, 184])
def test_a_soft_disk_touching_a_rigid_one_is_not_an_overlap(tmp_path, elements):
    """A meshed disk of radius 0.5 and a rigid one whose centres are exactly 1 apart touch: the
    scene is valid for any mesh, e.g. 184 asked elements (181 triangles), whose bounding box is
    not centred on the circle (its middle is 1.5e-3 off towards the rigid disk, three times the
    overlap the check tolerates). Brought 0.01 closer, they overlap and the scene is refused."""
    from pre.mesh import reference_disk_mesh
    from pre.scene import contact_laws, neo_hookean_material, rigid_material

    mesh = reference_disk_mesh(elements, "T3")
    points, cells = 0.5 * np.asarray(mesh.points)[:, :2] + (1.5, 2.0), np.asarray(mesh.cells)
    params = default_parameters((0, 4, 0, 4), 0.2, 1.0, [1.0])
    params["materials"] = {"rigid": rigid_material(1.0), "soft": neo_hookean_material("T3")}
    params["interactions"] = contact_laws(["rigid", "soft"], 0.2)
    for gap, valid in ((0.0, True), (-0.01, False)):
        folder = tmp_path / f"gap{gap}"
        write_scene(folder, params, [(1.5, 2.0), (2.5 + gap, 2.0)], [0.5, 0.5], ["soft", "rigid"],
                    meshes={0: (points, cells, "T3")})
        if valid:
            read_scene(folder)
        else:
            _expect(folder, "bodies.vtu", "points/radius", "non-overlapping bodies")
