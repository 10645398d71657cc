"""The scene schema: the docs show it, pre builds from it, compute reads with it."""

from pathlib import Path

import pytest

from compute import schema
from compute.errors import SceneError
from pre.scene import contact_laws, overridden, rigid_material, scene_parameters

ROOT = Path(__file__).resolve().parents[2]


def test_formats_doc_shows_the_schema():
    text = (ROOT / "docs" / "FORMATS.md").read_text()
    block = text.split(schema.BEGIN)[1].split(schema.END)[0]
    assert block.strip() == schema.markdown().strip(), "run: python -m compute.schema docs/FORMATS.md"


def test_every_key_is_documented_once_with_a_range_or_options():
    tables = [schema.TOP, schema.BODIES, schema.INTERACTION, *schema.MATERIALS.values(), *schema.SETTINGS.values()]
    for keys in tables:
        names = [k.name for k in keys]
        assert len(names) == len(set(names))
        for k in keys:
            assert k.doc
            if k.type in ("float", "int", "floats"):
                assert k.low is not None and k.high is not None, k.name  # every number has a finite range
    settings = [k.name for keys in schema.SETTINGS.values() for k in keys]
    assert len(settings) == len(set(settings))  # pre routes settings by name


def _minimal(**overrides):
    settings = dict(xmin=0.0, xmax=1.0, ymin=0.0, ymax=1.0, mass=1.0, control="pressure", pressures=[1.0],
                    phi_tolerance=1e-4, inertial_tolerance=1e-4, check_every=10, max_steps_per_stage=100,
                    gravity=[0.0, 0.0], time_step=0.1, theta=1.0, contact_tolerance=1e-6, nlgs_max_sweeps=100,
                    relaxation=1.0, skin=0.1, frames="stages", every_steps=0, checkpoint_every_steps=10)
    settings.update(overrides)
    return scene_parameters({"rigid": rigid_material()}, contact_laws(["rigid"], 0.3), **settings)


def test_pre_writes_every_default_out():
    p = _minimal()
    for table, keys in schema.SETTINGS.items():
        for k in keys:
            if k.when is None:
                assert k.name in p[table], f"{table}.{k.name}"
    assert p["solver"]["newton_max_iterations"] == 20 and p["solver"]["contact"] == "auto"


def test_pre_refuses_a_misspelt_or_missing_setting():
    with pytest.raises(SceneError, match="did you mean time_step"):
        _minimal(time_stepp=0.1)
    p = _minimal()
    with pytest.raises(SceneError, match="solver.theta"):
        overridden(p, {"solver.theta": 2.0})
    with pytest.raises(SceneError, match="did you mean solver.time_step"):
        overridden(p, {"solver.timestep": 0.1})
    with pytest.raises(SceneError, match="loading.pressures"):
        _minimal(pressures=[-1.0])


def test_formats_doc_example_is_a_valid_scene():
    import tomllib

    from compute.scene import parse_parameters

    text = (ROOT / "docs" / "FORMATS.md").read_text()
    example = text.split("```toml\n", 1)[1].split("```", 1)[0]
    parse_parameters("docs/FORMATS.md", tomllib.loads(example))


def test_copy_scene_applies_overrides_and_names_the_source_file(tmp_path):
    import numpy as np

    from compute.scene import read_scene
    from pre.scene import copy_scene, write_scene

    source = write_scene(tmp_path / "a", _minimal(), np.full((1, 2), 0.5), np.full(1, 0.25), ["rigid"])
    copy = copy_scene(source, tmp_path / "b", {"loading.check_every": 5, "solver.contact": "nlgs"})
    scene = read_scene(copy)
    assert scene.loading.check_every == 5 and scene.solver.contact == "nlgs"
    assert (copy / "bodies.vtu").read_bytes() == (source / "bodies.vtu").read_bytes()
    assert read_scene(source).loading.check_every == 10  # the source is left as it was
    with pytest.raises(SceneError, match=r"a/scene.toml: field 'loading.check_every'"):
        copy_scene(source, tmp_path / "c", {"loading.check_every": 0})
