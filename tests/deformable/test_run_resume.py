"""A deformable run through compute.run: frames readable by post, and resume from a checkpoint
gives the same stages as an uninterrupted run."""

import numpy as np
import pytest

from compute.run import Run
from pre import single_particle


class Stop(Exception):
    pass


def test_resume_continues_a_deformable_run(tmp_path):
    single_particle.write(tmp_path / "scene", element="T3", pressures=[1e-3, 1e-2, 3e-2])
    toml = tmp_path / "scene" / "scene.toml"
    toml.write_text(toml.read_text().replace("checkpoint_every_steps = 1000", "checkpoint_every_steps = 3"))
    full = Run(tmp_path / "scene", tmp_path / "full", log=lambda m: None).execute()

    def stop_after_first_stage(msg):
        if "stage 0" in msg and "equilibrated" in msg:
            raise Stop

    with pytest.raises(Stop):
        Run(tmp_path / "scene", tmp_path / "cut", log=stop_after_first_stage).execute()
    messages = []
    resumed = Run(tmp_path / "scene", tmp_path / "cut", resume=True, log=messages.append).execute()
    assert messages[0].startswith("resuming from step")
    np.testing.assert_array_equal(resumed.q, full.q)  # bitwise: checkpoints are restart points

    from post.table import measure_output

    rows = measure_output(tmp_path / "cut", min_contacts=1)
    reference = measure_output(tmp_path / "full", min_contacts=1)
    assert [r["stage"] for r in rows] == [0, 1, 2]
    np.testing.assert_allclose([r["phi"] for r in rows], [r["phi"] for r in reference], rtol=1e-5)
    for r in rows:
        assert r["P_walls"] == pytest.approx(r["pressure_applied"], rel=1e-4)
        assert abs(r["P_rel_diff"]) < 1e-6  # stress from contacts = stress from walls
        assert r["Z"] == 4.0
