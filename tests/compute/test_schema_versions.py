"""Scene files of an older schema version: read in the current layout, and a run started under
one resumes; an old key's name in a current file is an error naming the new one.

Version 1 named ``solver.contact_tolerance`` ``solver.nlgs_tolerance``; a version-1 file is
written here as pre wrote them then: the current file with those two lines changed back."""

import shutil
from pathlib import Path

import pytest

from compute import schema
from compute.errors import OutputFolderError, SceneError
from compute.run import Run, run
from compute.scene import read_parameters, read_scene
from pre.scene import contact_laws, overridden, rigid_material, scene_parameters
from tests.compute.scenes import small_rigid_scene


def _as_version_1(scene: Path) -> Path:
    """Rewrite ``scene``/scene.toml as a version-1 file; returns the scene folder."""
    toml = scene / "scene.toml"
    text = toml.read_text()
    assert text.count("schema_version = 2\n") == 1 and text.count("\ncontact_tolerance = ") == 1
    toml.write_text(text.replace("schema_version = 2\n", "schema_version = 1\n")
                    .replace("\ncontact_tolerance = ", "\nnlgs_tolerance = "))
    return scene


def _settings(**overrides):
    settings = dict(xmin=0.0, xmax=1.0, ymin=0.0, ymax=1.0, mass=1.0, control="pressure", pressures=[1.0],
                    phi_tolerance=1e-4, inertial_tolerance=1e-4, check_every=10, max_steps_per_stage=100,
                    gravity=[0.0, 0.0], time_step=0.1, theta=1.0, contact_tolerance=1e-6, nlgs_max_sweeps=100,
                    relaxation=1.0, skin=0.1, frames="stages", every_steps=0, checkpoint_every_steps=10)
    return {**settings, **overrides}


def test_a_version_1_scene_is_read_as_version_2(tmp_path):
    scene = small_rigid_scene(tmp_path / "v2")
    old = _as_version_1(small_rigid_scene(tmp_path / "v1"))
    new, migrated = read_scene(scene), read_scene(old)
    assert migrated.solver == new.solver and migrated.solver.contact_tolerance == 1e-6  # pre's default
    assert migrated.raw == new.raw and migrated.raw["schema_version"] == schema.SCHEMA_VERSION == 2
    assert read_parameters(old / "scene.toml")["solver"] == new.solver


def test_the_old_key_in_a_version_2_file_names_the_file_and_the_new_key(tmp_path):
    scene = small_rigid_scene(tmp_path / "scene")
    toml = scene / "scene.toml"
    toml.write_text(toml.read_text().replace("\ncontact_tolerance = ", "\nnlgs_tolerance = "))
    with pytest.raises(SceneError) as err:
        read_scene(scene)
    message = str(err.value)
    assert str(toml) in message and "'solver.nlgs_tolerance'" in message and "contact_tolerance" in message
    assert "schema_version 2" in message


def test_a_version_1_file_with_the_new_key_is_an_error(tmp_path):
    scene = _as_version_1(small_rigid_scene(tmp_path / "scene"))
    toml = scene / "scene.toml"
    toml.write_text(toml.read_text().replace("\nnlgs_tolerance = ", "\ncontact_tolerance = "))
    with pytest.raises(SceneError, match=r"field 'solver.contact_tolerance': expected nlgs_tolerance, its name in "
                                         r"a schema_version 1 file"):
        read_scene(scene)


def test_pre_names_the_new_key_for_the_old_one():
    laws = contact_laws(["rigid"], 0.3)
    settings = _settings()
    settings["nlgs_tolerance"] = settings.pop("contact_tolerance")
    with pytest.raises(SceneError, match="field 'nlgs_tolerance': expected contact_tolerance"):
        scene_parameters({"rigid": rigid_material()}, laws, **settings)
    p = scene_parameters({"rigid": rigid_material()}, laws, **_settings())
    with pytest.raises(SceneError, match="field 'solver.nlgs_tolerance': expected solver.contact_tolerance"):
        overridden(p, {"solver.nlgs_tolerance": 1e-8})
    old = {**p, "schema_version": 1,
           "solver": {("nlgs_tolerance" if k == "contact_tolerance" else k): v for k, v in p["solver"].items()}}
    assert overridden(old, {"solver.contact_tolerance": 1e-8}) == overridden(p, {"solver.contact_tolerance": 1e-8})


class _Killed(BaseException):
    """Stands for the end of a process killed right after a checkpoint."""


def _run_killed_after_checkpoint(scene: Path, out: Path, step: int, monkeypatch) -> None:
    checkpoint = Run.checkpoint

    def killing_checkpoint(self):
        checkpoint(self)
        if self.state.step == step:
            raise _Killed

    with monkeypatch.context() as m:
        m.setattr(Run, "checkpoint", killing_checkpoint)
        with pytest.raises(_Killed):
            run(scene, out, log=lambda msg: None)


@pytest.mark.parametrize("scene_now", ["version 1", "version 2"])
def test_a_run_started_under_version_1_resumes(tmp_path, monkeypatch, scene_now):
    """A run of a version-1 scene stopped after a checkpoint (its copy OUT/scene.toml of
    version 1) resumes from its scene folder, left as it was or rewritten in version 2, and ends
    as the uninterrupted run of the version-2 scene: the same history, byte for byte."""
    reference = tmp_path / "reference"
    run(small_rigid_scene(tmp_path / "v2"), reference, log=lambda msg: None)
    scene = _as_version_1(small_rigid_scene(tmp_path / "v1"))
    out = tmp_path / "out"
    _run_killed_after_checkpoint(scene, out, 20, monkeypatch)
    assert "nlgs_tolerance" in (out / "scene.toml").read_text()
    if scene_now == "version 2":
        shutil.copyfile(tmp_path / "v2" / "scene.toml", scene / "scene.toml")
    logged = []
    run(scene, out, resume=True, log=logged.append)
    assert any(msg.startswith("resuming from step 20") for msg in logged), logged
    assert (out / "history.csv").read_bytes() == (reference / "history.csv").read_bytes()
    assert (out / "COMPLETE").read_bytes() == (reference / "COMPLETE").read_bytes()


def test_a_resumed_run_still_refuses_a_changed_scene(tmp_path, monkeypatch):
    """Migration does not hide a change: the tolerance itself changed is refused, named by its
    current name."""
    scene = _as_version_1(small_rigid_scene(tmp_path / "scene"))
    out = tmp_path / "out"
    _run_killed_after_checkpoint(scene, out, 10, monkeypatch)
    toml = scene / "scene.toml"
    text = toml.read_text()
    assert "\nnlgs_tolerance = 1e-06\n" in text
    toml.write_text(text.replace("\nnlgs_tolerance = 1e-06\n", "\nnlgs_tolerance = 1e-07\n"))
    with pytest.raises(OutputFolderError, match="changed: solver.contact_tolerance"):
        run(scene, out, resume=True, log=lambda msg: None)
