"""Narrow phase: gap, frame and kinematic rows of every candidate contact.

Conventions (docs/FORMATS.md): a contact is between body i and body j (j < 0 for a wall); the
normal n points from i towards j and t = (-n_y, n_x). The relative velocity at the contact is
u = H^T v with

    u_n = n . (v_j(x_c) - v_i(x_c))    (= d gap / dt),    u_t = t . (v_j(x_c) - v_i(x_c)),

and the contact impulse r = r_n n + r_t t acts on j (and -r on i), so that the generalised
impulse is H r. H is stored sparsely: per contact up to ``MAX_DOFS`` (dof index, n-row, t-row).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

MAX_DOFS = 8
WALL_NORMALS = np.array([[-1.0, 0.0], [1.0, 0.0], [0.0, -1.0], [0.0, 1.0]])  # from disk to wall
WALL_AXES = np.array([[1.0, 0.0], [1.0, 0.0], [0.0, 1.0], [0.0, 1.0]])  # direction of the wall dof


@dataclass
class ContactRows:
    """Arrays over the nc candidate contacts of one step (shapes in brackets).

    ``pairs`` (nc, 2) the candidate pairs in the numbering of the detector that made them,
    ``body_i``, ``body_j`` (nc,) global ids (j = -1..-4 for walls), ``dof``, ``hn``, ``ht``
    (nc, MAX_DOFS) the sparse rows of H (dof = -1 unused), ``gap`` (nc,), ``normal`` (nc, 2),
    ``point`` (nc, 2), ``branch`` (nc, 2), ``mu`` (nc,), ``impulse`` (nc, 2) = (r_n, r_t).
    """

    pairs: np.ndarray
    body_i: np.ndarray
    body_j: np.ndarray
    dof: np.ndarray
    hn: np.ndarray
    ht: np.ndarray
    gap: np.ndarray
    normal: np.ndarray
    point: np.ndarray
    branch: np.ndarray
    mu: np.ndarray
    impulse: np.ndarray

    @classmethod
    def empty(cls, n: int) -> "ContactRows":
        return cls(
            pairs=np.zeros((n, 2), np.int64), body_i=np.zeros(n, np.int64), body_j=np.zeros(n, np.int64),
            dof=np.full((n, MAX_DOFS), -1, np.int64), hn=np.zeros((n, MAX_DOFS)), ht=np.zeros((n, MAX_DOFS)),
            gap=np.zeros(n), normal=np.zeros((n, 2)), point=np.zeros((n, 2)), branch=np.zeros((n, 2)),
            mu=np.zeros(n), impulse=np.zeros((n, 2)),
        )

    def __len__(self) -> int:
        return len(self.gap)

    def forces(self, h: float) -> np.ndarray:
        """The contact forces (nc, 2) = (f_n, f_t) of the impulses over a step of length ``h``: the
        mean force r / h over the step. The one place impulses become forces (frames, wall
        forces): a step taken in sub-steps leaves impulses rescaled to the whole step
        (compute.stepping.control), so ``h`` is the run's time step."""
        return self.impulse / h

    @classmethod
    def concatenate(cls, parts: list["ContactRows"]) -> "ContactRows":
        names = cls.__dataclass_fields__
        return cls(**{k: np.concatenate([getattr(p, k) for p in parts]) for k in names})


@numba.njit(cache=True)
def disk_disk_rows(pairs, centres, radii, dof0, dof, hn, ht, gap, normal, point, branch):
    """Fill the rows of rigid disk pairs (a, b); disk k has dofs dof0[k] + (0, 1, 2) = (x, y, rot)."""
    for c in range(pairs.shape[0]):
        a, b = pairs[c, 0], pairs[c, 1]
        dx = centres[b, 0] - centres[a, 0]
        dy = centres[b, 1] - centres[a, 1]
        dist = np.sqrt(dx * dx + dy * dy)
        nx, ny = dx / dist, dy / dist
        tx, ty = -ny, nx
        g = dist - radii[a] - radii[b]
        gap[c] = g
        normal[c, 0], normal[c, 1] = nx, ny
        s = radii[a] + 0.5 * g
        point[c, 0] = centres[a, 0] + s * nx
        point[c, 1] = centres[a, 1] + s * ny
        branch[c, 0], branch[c, 1] = dx, dy
        for k in range(3):
            dof[c, k] = dof0[a] + k
            dof[c, 3 + k] = dof0[b] + k
        hn[c, 0], hn[c, 1], hn[c, 2] = -nx, -ny, 0.0
        hn[c, 3], hn[c, 4], hn[c, 5] = nx, ny, 0.0
        ht[c, 0], ht[c, 1], ht[c, 2] = -tx, -ty, -radii[a]
        ht[c, 3], ht[c, 4], ht[c, 5] = tx, ty, -radii[b]


@numba.njit(cache=True)
def disk_wall_rows(pairs, centres, radii, dof0, bounds, wall_dof0, normals, axes,
                   dof, hn, ht, gap, normal, point, branch):
    """Fill the rows of (disk a, wall w) pairs; wall w has the single dof wall_dof0 + w."""
    for c in range(pairs.shape[0]):
        a, w = pairs[c, 0], pairs[c, 1]
        nx, ny = normals[w, 0], normals[w, 1]
        tx, ty = -ny, nx
        # signed distance from the disk surface to the wall, along n
        g = (bounds[w] - centres[a, 0]) * nx if w < 2 else (bounds[w] - centres[a, 1]) * ny
        g -= radii[a]
        gap[c] = g
        normal[c, 0], normal[c, 1] = nx, ny
        ell = radii[a] + g
        point[c, 0] = centres[a, 0] + ell * nx
        point[c, 1] = centres[a, 1] + ell * ny
        branch[c, 0], branch[c, 1] = ell * nx, ell * ny
        for k in range(3):
            dof[c, k] = dof0[a] + k
        dof[c, 3] = wall_dof0 + w
        hn[c, 0], hn[c, 1], hn[c, 2] = -nx, -ny, 0.0
        ht[c, 0], ht[c, 1], ht[c, 2] = -tx, -ty, -radii[a]
        hn[c, 3] = nx * axes[w, 0] + ny * axes[w, 1]
        ht[c, 3] = tx * axes[w, 0] + ty * axes[w, 1]


@numba.njit(cache=True, inline="always")
def local_velocity(dof, hn, ht, c, v):
    """(H_n,cᵀ v, H_t,cᵀ v): the normal and tangential velocities of contact c for velocities v."""
    un = 0.0
    ut = 0.0
    for k in range(dof.shape[1]):
        d = dof[c, k]
        if d >= 0:
            un += hn[c, k] * v[d]
            ut += ht[c, k] * v[d]
    return un, ut


@numba.njit(cache=True)
def generalised_impulse(dof, hn, ht, r, n_dofs):
    """H r (n_dofs,) for the sparse rows dof, hn, ht (nc, MAX_DOFS) and impulses r (nc, 2)."""
    hr = np.zeros(n_dofs)
    for c in range(dof.shape[0]):
        if r[c, 0] == 0.0 and r[c, 1] == 0.0:
            continue
        for k in range(dof.shape[1]):
            d = dof[c, k]
            if d >= 0:
                hr[d] += hn[c, k] * r[c, 0] + ht[c, k] * r[c, 1]
    return hr
