"""A run killed (SIGKILL) at any moment and resumed with --resume ends bitwise identical to the
uninterrupted run: history, frame list, every frame file and the final state. One soft-body scene
(whose steps reuse factorisations), the same with its inertia scaled per stage, and one rigid
scene, each killed at three moments: before the first checkpoint, right after a checkpoint, and
mid-way between two checkpoints."""

import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from pre import single_particle
from tests.compute.test_restart import _scene as rigid_scene

# runs the scene and kills itself with SIGKILL right after the given moment
KILLER = textwrap.dedent("""
    import os, signal, sys
    from compute import run as r
    scene, out, moment, step = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
    record, checkpoint = r.Run._record, r.Run.checkpoint

    def killing_record(self, *a):
        phi = record(self, *a)
        if moment == "step" and self.state.step == step:
            os.kill(os.getpid(), signal.SIGKILL)
        return phi

    def killing_checkpoint(self):
        checkpoint(self)
        if moment == "checkpoint" and self.state.step == step:
            os.kill(os.getpid(), signal.SIGKILL)

    r.Run._record, r.Run.checkpoint = killing_record, killing_checkpoint
    r.run(scene, out, log=lambda m: None)
""")


def _soft_scene(folder: Path) -> Path:
    single_particle.write(folder, element="T3", elements=40, pressures=[1e-3, 1e-2, 3e-2])
    toml = folder / "scene.toml"
    toml.write_text(toml.read_text().replace("checkpoint_every_steps = 1000", "checkpoint_every_steps = 4"))
    return folder


def _stage_set_scene(folder: Path) -> Path:
    """The soft scene with its inertia scaled in every stage (solver.mass_scaling 50: 1.25, 12.5,
    37.5 times the material's) and its walls damped from the stage ends written so far
    (walls.damping_ratio 1), which a resumed run must set again from its stage and frames."""
    _soft_scene(folder)
    toml = folder / "scene.toml"
    text = toml.read_text()
    assert "mass_scaling = 0.0" in text and "damping_ratio = 0.0" in text
    toml.write_text(text.replace("mass_scaling = 0.0", "mass_scaling = 50.0").replace("damping_ratio = 0.0",
                                                                                    "damping_ratio = 1.0"))
    return folder


def _rigid_scene(folder: Path) -> Path:
    return rigid_scene(folder)


SCENES = {"soft": (_soft_scene, 4), "soft, set per stage": (_stage_set_scene, 4), "rigid": (_rigid_scene, 25)}


def _compute(scene: Path, out: Path, *extra: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "compute", str(scene), "--out", str(out), *extra],
                          capture_output=True, text=True)


def _files(out: Path) -> dict[str, bytes]:
    names = ["history.csv", "frames.csv", *(f"frames/{p.name}" for p in sorted((out / "frames").glob("*.vtu")))]
    return {n: (out / n).read_bytes() for n in names}


@pytest.fixture(scope="module", params=sorted(SCENES))
def reference(request, tmp_path_factory):
    make, every = SCENES[request.param]
    folder = tmp_path_factory.mktemp(request.param)
    scene = make(folder / "scene")
    done = _compute(scene, folder / "ref")
    assert done.returncode == 0, done.stderr
    with np.load(folder / "ref" / "checkpoint" / "state.npz") as d:
        steps = int(d["scalars"][1])
    assert steps > 3 * every, "the scene is too short to be killed mid-way"
    return scene, folder / "ref", every


@pytest.mark.parametrize("moment", ["before the first checkpoint", "right after a checkpoint", "mid-way"])
def test_killed_run_resumes_bitwise(reference, moment, tmp_path):
    scene, ref, every = reference
    kind, step = {"before the first checkpoint": ("step", every - 1),
                  "right after a checkpoint": ("checkpoint", 2 * every),
                  "mid-way": ("step", 2 * every + every // 2 + 1)}[moment]
    out = tmp_path / "out"
    killed = subprocess.run([sys.executable, "-c", KILLER, str(scene), str(out), kind, str(step)],
                            capture_output=True, text=True)
    assert killed.returncode == -9, killed.stderr  # it was killed, not finished
    resumed = _compute(scene, out, "--resume")
    assert resumed.returncode == 0, resumed.stderr
    expected, got = _files(ref), _files(out)
    assert list(got) == list(expected)
    for name in expected:
        assert got[name] == expected[name], f"{name} differs from the uninterrupted run"
    with np.load(ref / "checkpoint" / "state.npz") as a, np.load(out / "checkpoint" / "state.npz") as b:
        assert sorted(a.files) == sorted(b.files)
        for k in a.files:
            assert np.array_equal(a[k], b[k], equal_nan=True), k
