"""The state of the soft elements in a run's checkpoint: how far the mesh is from what it can resolve.

For every soft group of RUN (a folder with scene/ and out/checkpoint/), at the checkpoint's
configuration: the range of the pointwise volume ratio J / J_ref over all stiffness points, the
number of bodies with some J / J_ref below 0.7 (impossible for a nearly incompressible material
at the loads of the study), and the largest element pressure and von Mises stress over E. A T3
disk that locks shows element pressures several times the applied P; a mean-dilatation T6 disk
shows pointwise J far from 1 while its mean pressure stays moderate.

    python benchmarks/experiments/element_state.py --run W/runs/k1_mu0.2_s1
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
from pathlib import Path

import numpy as np


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--run", type=Path, required=True, help="a run folder with scene/ and out/ (with a checkpoint)")
    a = ap.parse_args()
    from compute.run import Run

    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "out"
        shutil.copytree(a.run / "out", out, ignore=shutil.ignore_patterns("frames", ".lock"))
        (out / "frames").mkdir()
        run = Run(a.run / "scene", out, resume=True, log=lambda msg: None)
        state = run.state
        print(f"step {state.step}, stage {state.stage}, phi {run.model.phi(state.q):.4f}")
        for g in run.model.soft:
            x = g.nodes(state.q)
            ratio = g.batch.jacobians(x) / g.batch.jacobians(g.batch.X)
            _, pressure, mises = g.batch.element_stresses(x)
            e = g.batch.material.young
            print(f"{g.batch.element.name} ({g.batch.volumetric}), {g.B} bodies: J/J_ref {ratio.min():.3f} .. "
                  f"{ratio.max():.3f}; bodies with J/J_ref < 0.7: {int((ratio.min(axis=(1, 2)) < 0.7).sum())}; "
                  f"element pressure / E: max {pressure.max() / e:.2f}, 99th percentile "
                  f"{np.percentile(pressure, 99) / e:.2f}; von Mises / E: max {mises.max() / e:.2f}")
        run.history.close()


if __name__ == "__main__":
    main()
