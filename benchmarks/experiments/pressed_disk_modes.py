"""Negative modes of a pressed single particle's Newton matrix at the end of every stage, and
where they live: on the boundary nodes that touch no wall (the free surface), on those that
touch one, or inside.

For each scene (a single-particle scene folder; typically the same disk with
``--volumetric mean_dilatation`` and ``standard``) the loading program is run; at the last step
of every stage A = M + h²θ² K_t of the disk is formed (dense) and its negative eigenvalues are
counted. Each negative eigenvector's weight |v_a|² is summed over three node sets: boundary
nodes not on a wall (farther than 1e-8 from the disk's bounding box, which the walls touch),
boundary nodes on a wall (and, of those on one wall only, the part along it: sliding),
interior nodes; the sums are averaged over the negative modes. Also prints the Newton iterations of every stage
(benchmarks/newton_iterations.py's counting).

    python -m studies.single_particle.pre --workdir MD --elements 92 --volumetric mean_dilatation
    python -m studies.single_particle.pre --workdir ST --elements 92 --volumetric standard
    python benchmarks/experiments/pressed_disk_modes.py MD/scene ST/scene

Prints markdown.
"""

from __future__ import annotations

import os

for _var in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import io  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.append(str(Path(__file__).resolve().parents[1]))  # benchmarks/: the shared helpers
import checkout  # noqa: E402
from newton_iterations import count_per_stage  # noqa: E402
from tangent_modes import dense  # noqa: E402

ON_WALL = 1e-8  # a boundary node this close to the disk's bounding box touches a wall


def stage_ends(scene: Path) -> tuple:
    """Run the scene; (model, h, θ, {stage: (q, P, φ)} at each stage's last step, Newton
    iterations per stage)."""
    from compute.progress import Display
    from compute.run import Run

    with tempfile.TemporaryDirectory() as tmp:
        run = Run(scene, Path(tmp) / "out", log=lambda m: None, display=Display(1, stream=io.StringIO()))
        counts = count_per_stage(run)
        step, ends = run.stepper.step, {}

        def recording(state, pressure, *args, **kwargs):
            rep = step(state, pressure, *args, **kwargs)
            ends[state.stage] = (state.q.copy(), pressure, run.model.phi(state.q))
            return rep

        run.stepper.step = recording
        run.execute()
    return run.model, run.stepper.h, run.stepper.theta, ends, counts["stage_iterations"]


def modes(group, q: np.ndarray, h: float, theta: float) -> dict:
    """Negative eigenvalues of A = M + h²θ² K_t of soft body 0 at q, the lowest, and the summed
    weight of their eigenvectors on free-surface, on-wall and interior nodes."""
    b = group.batch
    x = group.nodes(q)[:1].copy()
    f, k = np.zeros((1, b.n_dof)), np.zeros_like(b.mass_data[:1])
    b.internal_force_and_tangent(x, np.array([True]), f, k)
    w, V = np.linalg.eigh(dense(b, b.mass_data[0]) + (h * theta) ** 2 * dense(b, k[0]))
    negative = V[:, w < 0.0]
    boundary = np.zeros(x.shape[1], bool)
    boundary[b.boundary] = True
    lo, hi = x[0].min(axis=0), x[0].max(axis=0)
    touching = boundary[:, None] & ((x[0] - lo < ON_WALL) | (hi - x[0] < ON_WALL))  # (n_nodes, 2): an x / a y wall
    on_wall = touching.any(axis=1)
    squared = (negative**2).reshape(x.shape[1], 2, -1)  # (n_nodes, 2, n_negative)
    weight = squared.sum(axis=1)
    along = np.where(touching[:, 0] & ~touching[:, 1], squared[:, 1].sum(axis=1), 0.0) \
        + np.where(touching[:, 1] & ~touching[:, 0], squared[:, 0].sum(axis=1), 0.0)  # along one wall
    n = max(negative.shape[1], 1)
    share = {name: float(weight[mask].sum() / n)
             for name, mask in (("free", boundary & ~on_wall), ("wall", on_wall), ("inside", ~boundary))}
    return {"count": negative.shape[1], "lowest": float(w[0]), "free_nodes": int((boundary & ~on_wall).sum()),
            "along": float(along.sum() / n), **share}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenes", type=Path, nargs="+", help="single-particle scene folders")
    a = ap.parse_args()
    sys.path.insert(0, os.getcwd())
    print(f"# Negative modes of the pressed single particle, by stage (commit {checkout.commit()})\n")
    for scene in a.scenes:
        model, h, theta, ends, iterations = stage_ends(scene)
        group = model.soft[0]
        print(f"\n## {scene} ({group.batch.element.name}, {group.batch.cells.shape[0]} elements, "
              f"{group.batch.volumetric}), h = {h:g}\n")
        print("| stage | P/E | φ | Newton its | negative eigenvalues of A | lowest | free-surface nodes "
              "| weight on free surface / on walls (along them) / inside |")
        print("|---|---|---|---|---|---|---|---|")
        for stage in sorted(ends):
            q, p, phi = ends[stage]
            m = modes(group, q, h, theta)
            print(f"| {stage} | {p:.3g} | {phi:.5f} | {iterations[stage]} | {m['count']} | {m['lowest']:.3g} "
                  f"| {m['free_nodes']} | {m['free']:.2f} / {m['wall']:.2f} ({m['along']:.2f}) / {m['inside']:.2f} |")


if __name__ == "__main__":
    main()
