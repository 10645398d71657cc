"""A scene with soft bodies gives the same run, byte for byte, whatever BLAS kernel the processor
selects (compute.fixed_order): each run in a child process forced onto another OpenBLAS kernel
(OPENBLAS_CORETYPE), the history and frames compared. Before the fixed-order sums the two
frictionless runs below parted within their first steps."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from tests.blas_kernels import kernel_environment, needs_openblas_kernels
from tests.deformable import scenes

KERNELS = ("Prescott", "Haswell")  # SSE3 and AVX2 with fused multiply-adds: two orders of summing


def _scene(folder: Path, friction: float, solver: str) -> Path:
    """Four T3 soft disks and two rigid ones pressed by the walls: 12 steps with Newton iterations
    (and so Anderson's mixing), contacts solved by ``solver``."""
    soft = [scenes.disk(30, "T3", centre=c, radius=1.0) for c in ((0.0, 0.0), (2.1, 0.0), (0.0, 2.1), (2.1, 2.1))]
    rigid = [((4.2, 0.0), 1.0), ((4.2, 2.1), 1.0)]
    params = scenes.parameters((-1.1, 5.3, -1.1, 3.2), element="T3", friction=friction, time_step=0.5,
                               contact_tolerance=1e-8, pressures=(0.01, 0.03), max_steps=12)
    params["solver"]["contact"] = solver
    params["output"].update(every_steps=4)
    return scenes.write(folder, params, soft=soft, rigid=rigid)


def _files(out: Path) -> dict[str, bytes]:
    names = ["history.csv", *(f"frames/{p.name}" for p in sorted((out / "frames").glob("*.vtu")))]
    return {n: (out / n).read_bytes() for n in names}


@needs_openblas_kernels
@pytest.mark.parametrize("friction, solver", ((0.0, "mprgp"), (0.3, "nlgs_block")))
def test_a_soft_run_is_the_same_on_every_blas_kernel(tmp_path, friction, solver):
    scene = _scene(tmp_path / "scene", friction, solver)
    runs = {}
    for kernel in KERNELS:
        out = tmp_path / kernel
        done = subprocess.run([sys.executable, "-m", "compute", str(scene), "--out", str(out), "--threads", "1"],
                              env=kernel_environment(kernel), capture_output=True, text=True, timeout=600)
        assert done.returncode in (0, 1), done.stderr  # 1: a stage not equilibrated in 12 steps
        runs[kernel] = _files(out)
    first, second = (runs[k] for k in KERNELS)
    assert len(first) > 2 and list(first) == list(second)
    assert first["history.csv"].count(b"\n") > 10
    for name in first:
        assert first[name] == second[name], f"{name} differs between the {KERNELS} kernels"
