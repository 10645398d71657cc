"""Broad phase: candidate pairs of disks on a cell grid, O(N), and wall candidates.

A pair (i, j), i < j, is a candidate when its nominal gap |x_i - x_j| - r_i - r_j is below
``skin``. The list is kept while no body has moved more than ``skin / 2`` since it was made
(a Verlet list), so the narrow phase of every step works on a short, fixed list.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def _cell_keys(centres, lo, cell, nx, ny):
    n = centres.shape[0]
    keys = np.empty(n, np.int64)
    for i in range(n):
        cx = min(max(int((centres[i, 0] - lo[0]) / cell), 0), nx - 1)
        cy = min(max(int((centres[i, 1] - lo[1]) / cell), 0), ny - 1)
        keys[i] = cy * nx + cx
    return keys


@numba.njit(cache=True)
def _scan(centres, radii, skin, order, start, keys, nx, ny, out, count_only):
    """Visit each pair of neighbouring cells once; count or store candidate pairs."""
    m = 0
    n = centres.shape[0]
    for i in range(n):
        cx = keys[i] % nx
        cy = keys[i] // nx
        for dy in range(-1, 2):
            y = cy + dy
            if y < 0 or y >= ny:
                continue
            for dx in range(-1, 2):
                x = cx + dx
                if x < 0 or x >= nx:
                    continue
                c = y * nx + x
                for s in range(start[c], start[c + 1]):
                    j = order[s]
                    if j <= i:
                        continue
                    ddx = centres[j, 0] - centres[i, 0]
                    ddy = centres[j, 1] - centres[i, 1]
                    reach = radii[i] + radii[j] + skin
                    if ddx * ddx + ddy * ddy < reach * reach:
                        if not count_only:
                            out[m, 0] = i
                            out[m, 1] = j
                        m += 1
    return m


def disk_pairs(centres: np.ndarray, radii: np.ndarray, skin: float) -> np.ndarray:
    """Candidate pairs (m, 2), i < j, of disks (n, 2) centres / (n,) radii within ``skin``."""
    n = len(radii)
    if n < 2:
        return np.zeros((0, 2), np.int64)
    cell = 2.0 * float(radii.max()) + skin
    lo = centres.min(axis=0) - 1e-9
    nx = max(1, int((centres[:, 0].max() - lo[0]) / cell) + 1)
    ny = max(1, int((centres[:, 1].max() - lo[1]) / cell) + 1)
    keys = _cell_keys(centres, lo, cell, nx, ny)
    order = np.argsort(keys, kind="stable")
    start = np.searchsorted(keys[order], np.arange(nx * ny + 1))
    dummy = np.zeros((0, 2), np.int64)
    m = _scan(centres, radii, skin, order, start, keys, nx, ny, dummy, True)
    out = np.empty((m, 2), np.int64)
    _scan(centres, radii, skin, order, start, keys, nx, ny, out, False)
    return out


def wall_pairs(centres: np.ndarray, radii: np.ndarray, bounds: np.ndarray, skin: float) -> np.ndarray:
    """Candidate (disk, wall) pairs (m, 2); walls 0..3 = xmin, xmax, ymin, ymax."""
    gaps = np.column_stack([
        centres[:, 0] - bounds[0], bounds[1] - centres[:, 0],
        centres[:, 1] - bounds[2], bounds[3] - centres[:, 1],
    ]) - radii[:, None]
    i, w = np.nonzero(gaps < skin)
    return np.column_stack([i, w]).astype(np.int64)
