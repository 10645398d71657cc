"""How far a single particle rolled: the best-fit rigid rotation of its mesh in every frame.

For each frame OUT/frames/bodies_*.vtu of a run, the angle θ that minimises
Σ_a |R(θ) (X_a − X̄) − (x_a − x̄)|² over the mesh nodes (reference X = x − displacement):
tan θ = Σ (X × x) / Σ (X · x) with both centred (the 2D Procrustes rotation).

    python benchmarks/frame_rotation.py OUT [OUT ...]

Prints one line per run: the angles in degrees, frame by frame.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import meshio
import numpy as np


def best_fit_angle(X: np.ndarray, x: np.ndarray) -> float:
    """The rotation (radians) that best maps reference nodes X (n, 2) onto x (n, 2), both centred."""
    X, x = X - X.mean(axis=0), x - x.mean(axis=0)
    return float(np.arctan2(np.sum(X[:, 0] * x[:, 1] - X[:, 1] * x[:, 0]), np.sum(X * x)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", type=Path, nargs="+", help="output folders of python -m compute")
    for out in ap.parse_args().runs:
        angles = []
        for frame in sorted((out / "frames").glob("bodies_*.vtu")):
            m = meshio.read(frame)
            x = m.points[:, :2]
            angles.append(np.degrees(best_fit_angle(x - m.point_data["displacement"][:, :2], x)))
        print(f"{out}: " + " ".join(f"{a:.1f}" for a in angles))


if __name__ == "__main__":
    main()
