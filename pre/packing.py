"""Random polydisperse disk packings placed without overlap (before any compression)."""

from __future__ import annotations

import numpy as np


def polydisperse_radii(n: int, mean_diameter: float = 1.0, spread: float = 0.2,
                       rng: np.random.Generator | None = None) -> np.ndarray:
    """Radii (n,): diameters uniform in [(1 - spread), (1 + spread)] × mean_diameter."""
    if n < 1:
        raise ValueError(f"n: expected a number of disks >= 1, got {n}")
    if not 0.0 <= spread < 1.0:
        raise ValueError(f"spread: expected 0 <= spread < 1, got {spread}")
    rng = rng or np.random.default_rng()
    return 0.5 * mean_diameter * rng.uniform(1.0 - spread, 1.0 + spread, n)


def random_loose_packing(radii: np.ndarray, phi: float = 0.5, rng: np.random.Generator | None = None,
                         max_tries: int = 10000) -> tuple[np.ndarray, tuple[float, float, float, float]]:
    """Place disks of ``radii`` (n,) at random without overlap in a square box of packing fraction ``phi``.

    Random sequential addition, largest disks first, on a cell grid. Returns centres (n, 2) and
    the box (0, L, 0, L). Raises ValueError if a disk cannot be placed (``phi`` too high: RSA
    saturates near 0.55).
    """
    rng = rng or np.random.default_rng()
    if not 0.0 < phi <= 0.55:
        raise ValueError(f"phi: expected 0 < phi <= 0.55 for random sequential addition, got {phi}")
    side = float(np.sqrt(np.pi * np.sum(radii**2) / phi))
    rmax = float(radii.max())
    cell = 2.0 * rmax
    nc = max(1, int(side / cell))
    cell = side / nc
    grid: dict[tuple[int, int], list[int]] = {}
    centres = np.zeros((len(radii), 2))
    for i in np.argsort(-radii):
        r = radii[i]
        for _ in range(max_tries):
            p = rng.uniform(r, side - r, 2)
            cx, cy = int(p[0] / cell), int(p[1] / cell)
            near = [j for dx in (-1, 0, 1) for dy in (-1, 0, 1) for j in grid.get((cx + dx, cy + dy), ())]
            if not near or np.all(np.hypot(*(centres[near] - p).T) >= radii[near] + r):
                centres[i] = p
                grid.setdefault((cx, cy), []).append(i)
                break
        else:
            raise ValueError(f"phi: could not place disk {i} after {max_tries} tries at phi = {phi}")
    return centres, (0.0, side, 0.0, side)
