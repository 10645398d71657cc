"""Where the single particle's Newton iterations go: the negative modes of its Newton matrix, and
the iteration counts with the tangent kept or renewed.

1. Runs the single-particle study scene (T6 default disk, 16 stages, h = 10) and, at the end of
   the given steps, takes the Newton matrix A = M + h²θ² K_t of the disk at its configuration
   (dense; a few hundred dofs): its negative eigenvalues, the overlap of their eigenvectors
   with the rigid rotation about the centroid and with the two translations (unit vectors), and
   the share of the volumetric geometric stiffness G in their curvature (vᵀ h²θ² G v against
   vᵀ (A - h²θ² G) v). A negative mode is what makes the code fall back to A - G (or further)
   for the whole matrix (compute.bodies.soft_matrix).
2. Runs the same scene with the tangent as the code keeps it (evaluated at the first iteration
   of a step, refactorised when it changed by 5 % or the contraction was slow) and with the
   tangent evaluated and refactorised at every Newton iteration (monkeypatched here): steps,
   Newton iterations, factorisations and φ at the end of each stage.

    python -m studies.single_particle.pre --workdir W
    python benchmarks/experiments/tangent_modes.py --scene W/scene --steps 20 60 104 140 148

Prints markdown (results/tangent_modes.md holds one such output with its commit).
"""

from __future__ import annotations

import os

for _var in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import csv  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import scipy.sparse as sp  # noqa: E402

sys.path.append(str(Path(__file__).resolve().parents[1]))  # benchmarks/: the shared helpers
import checkout  # noqa: E402


def dense(batch, data) -> np.ndarray:
    """The (n, n) matrix of one body's CSR values ``data`` (nnz,)."""
    return sp.csr_matrix((data, batch.indices, batch.indptr), shape=(batch.n_dof, batch.n_dof)).toarray()


def rigid_modes(x: np.ndarray) -> dict:
    """Unit rigid-body fields (2n,) of nodes x (n, 2): rotation about their mean, translations."""
    c = x.mean(axis=0)
    rot = np.column_stack([-(x[:, 1] - c[1]), x[:, 0] - c[0]]).ravel()
    tx = np.tile([1.0, 0.0], len(x))
    ty = np.tile([0.0, 1.0], len(x))
    return {name: u / np.linalg.norm(u) for name, u in (("rotation", rot), ("x", tx), ("y", ty))}


def modes_at(group, q: np.ndarray, h: float, theta: float) -> dict:
    """Negative eigenvalues of A = M + h²θ² K_t of soft body 0 at q and their make-up."""
    b = group.batch
    x = group.nodes(q)[:1].copy()
    one = np.array([True])
    f, k, g = np.zeros((1, b.n_dof)), np.zeros_like(b.mass_data[:1]), np.zeros_like(b.mass_data[:1])
    b.internal_force_and_tangent(x, one, f, k)
    b.volumetric_geometric(x, one, g)
    c = (h * theta) ** 2
    A = dense(b, b.mass_data[0]) + c * dense(b, k[0])
    G = c * dense(b, g[0])
    w, V = np.linalg.eigh(A)
    neg = np.flatnonzero(w < 0.0)
    rigid = rigid_modes(x[0])
    return {"negative": [(float(w[i]), {n: float(abs(V[:, i] @ u)) for n, u in rigid.items()},
                          float(V[:, i] @ G @ V[:, i]), float(V[:, i] @ (A - G) @ V[:, i])) for i in neg],
            "smallest_positive": float(w[len(neg)]), "largest": float(w[-1]),
            "min_without_G": float(np.linalg.eigvalsh(A - G)[0])}


def run(scene: Path, steps: set, every_iteration: bool) -> dict:
    from compute.bodies import soft
    from compute.run import Run
    from compute.stepping import moreau_jean

    snaps: dict = {}
    step = moreau_jean.Stepper.step

    def recording(self, state, pressure, wall_speed=0.0):
        rep = step(self, state, pressure, wall_speed)
        if state.step in steps:
            snaps[state.step] = (state.q.copy(), pressure)
        return rep

    patches = [(moreau_jean.Stepper, "step", recording)]
    if every_iteration:
        free_velocity = soft.SoftBodies.free_velocity

        def renewing(self, v, out):
            if self._force is not None:
                self._force[:] = True  # the tangent evaluated and refactorised at every iteration
            return free_velocity(self, v, out)

        patches += [(soft.SoftBodies, "free_velocity", renewing), (soft.SoftBodies, "REFACTOR_CHANGE", -1.0)]
    saved = [(cls, name, cls.__dict__[name]) for cls, name, _ in patches]
    for cls, name, value in patches:
        setattr(cls, name, value)
    try:
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            r = Run(scene, Path(tmp) / "out", log=lambda m: None)
            r.execute()
            seconds = time.perf_counter() - t0
            rows = list(csv.DictReader(open(Path(tmp) / "out" / "history.csv")))
    finally:
        for cls, name, value in saved:
            setattr(cls, name, value)
    phi = {}
    for row in rows:
        phi[int(row["stage"])] = float(row["phi"])
    return {"model": r.model, "h": r.stepper.h, "theta": r.stepper.theta, "snaps": snaps, "stats": r.stepper.stats,
            "seconds": seconds, "phi": [phi[s] for s in sorted(phi)]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", type=Path, required=True, help="a single-particle scene folder")
    ap.add_argument("--steps", type=int, nargs="+", default=[20, 60, 104, 140, 148])
    a = ap.parse_args()
    sys.path.insert(0, os.getcwd())
    kept = run(a.scene, set(a.steps), every_iteration=False)
    renewed = run(a.scene, set(), every_iteration=True)
    group = kept["model"].soft[0]
    print(f"# Negative modes of the single particle's Newton matrix (commit {checkout.commit()})\n")
    print(f"`python benchmarks/experiments/tangent_modes.py --scene W/scene --steps {' '.join(map(str, a.steps))}`, "
          f"W from `python -m studies.single_particle.pre --workdir W`; h = {kept['h']:g}.\n")
    print("| step | P/E | negative eigenvalues of A | overlap with rotation, x, y | vᵀh²θ²Gv, vᵀ(A−h²θ²G)v "
          "| smallest positive, largest | smallest of A − h²θ²G |")
    print("|---|---|---|---|---|---|---|")
    for s in a.steps:
        if s not in kept["snaps"]:
            continue
        q, p = kept["snaps"][s]
        m = modes_at(group, q, kept["h"], kept["theta"])
        neg = m["negative"]
        first = neg[:3]
        print(f"| {s} | {p:.3g} | {len(neg)}: " + ", ".join(f"{w:.3g}" for w, *_ in first)
              + ("…" if len(neg) > 3 else "") + " | "
              + "; ".join(f"{o['rotation']:.3f}, {o['x']:.1e}, {o['y']:.1e}" for _, o, _, _ in first) + " | "
              + "; ".join(f"{gv:.3g}, {rv:.3g}" for _, _, gv, rv in first) + " | "
              + f"{m['smallest_positive']:.3g}, {m['largest']:.3g} | {m['min_without_G']:.3g} |")
    print("\n| tangent | steps | Newton iterations | factorisations (stabilised) | cuts | seconds (one thread) |")
    print("|---|---|---|---|---|---|")
    for name, r in (("kept (the code)", kept), ("renewed every iteration", renewed)):
        st = r["stats"]
        print(f"| {name} | {st['steps']} | {st['newton_iterations']} | {st['factorizations']} "
              f"({st['stabilised_factorizations']}) | {st['cuts']} | {r['seconds']:.1f} |")
    print("\nφ at the end of each stage, kept: " + ", ".join(f"{x:.5f}" for x in kept["phi"]))
    print("\nφ at the end of each stage, renewed: " + ", ".join(f"{x:.5f}" for x in renewed["phi"]))


if __name__ == "__main__":
    main()
