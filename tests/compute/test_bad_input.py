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
    _expect(scene, "scene.toml", "solver.time_step", "a number (missing)")


def test_mistyped_field(scene):
    _edit_toml(scene, r"^time_step = .*$", 'time_step = "fast"')
    _expect(scene, "scene.toml", "solver.time_step", "a number")


def test_out_of_range_field(scene):
    _edit_toml(scene, r"^theta = .*$", "theta = 0.2")
    _expect(scene, "scene.toml", "solver.theta", ">= 0.5")


def test_unknown_contact_solver(scene):
    _edit_toml(scene, r"^theta = (.*)$", r'theta = \1\ncontact = "lemke"')
    _expect(scene, "scene.toml", "solver.contact", "one of 'auto', 'nlgs', 'block'")


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
    _edit_toml(scene, r"^\[\[interactions\]\]$", "[[unused]]")
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
    _expect(scene, "bodies.vtu", "cell_data.radius", "positive radii")


def test_overlapping_bodies(scene):
    _rewrite_bodies(scene, [(1.0, 1.0), (1.5, 1.0), (1.0, 2.5)], RADII)
    _expect(scene, "bodies.vtu", "points/radius", "non-overlapping bodies")


def test_body_outside_walls(scene):
    _rewrite_bodies(scene, [(1.0, 1.0), (3.8, 1.0), (1.0, 2.5)], RADII)
    _expect(scene, "bodies.vtu", "radius/points of body 1", "inside the walls' box")


def test_truncated_bodies_file(scene):
    f = scene / "bodies.vtu"
    f.write_bytes(f.read_bytes()[: len(f.read_bytes()) // 2])
    _expect(scene, "bodies.vtu", "<file>", "a complete, readable VTU file")


def test_missing_bodies_field(scene):
    import meshio

    f = scene / "bodies.vtu"
    mesh = meshio.read(f, file_format="vtu")
    del mesh.cell_data["radius"]
    meshio.write(f, mesh, file_format="vtu")
    _expect(scene, "bodies.vtu", "cell_data.radius", "a cell array on every cell block")


def test_cli_reports_the_error(scene, tmp_path, capsys):
    from compute.__main__ import main

    _edit_toml(scene, r"^time_step = .*$", "time_step = -1.0")
    assert main([str(scene), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "scene.toml" in err and "solver.time_step" in err and "> 0" in err
