"""Newton solvers for the tests (the library has no static solver)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import spsolve

from compute.fem import FEBody


def newton(
    system: Callable[[np.ndarray], tuple[np.ndarray, sp.spmatrix]], u: np.ndarray, tol: float,
    max_iter: int = 25,
) -> np.ndarray:
    """Solve r(u) = 0 given system(u) -> (r, dr/du); stops when |r|_inf <= tol."""
    for _ in range(max_iter):
        r, jac = system(u)
        if np.abs(r).max() <= tol:
            return u
        u = u - spsolve(sp.csc_matrix(jac), r)
    raise AssertionError(f"Newton did not converge: |r| = {np.abs(r).max():.3e}")


def solve_static(
    body: FEBody, x: np.ndarray, fixed_dofs: np.ndarray, tol: float = 1e-12
) -> np.ndarray:
    """Equilibrium f_int = 0 on the free dofs, the fixed dofs kept at their values in x (n, 2)."""
    free = np.setdiff1d(np.arange(body.n_dof), fixed_dofs)
    flat = x.reshape(-1).copy()

    def system(u: np.ndarray) -> tuple[np.ndarray, sp.spmatrix]:
        flat[free] = u
        f, K = body.internal_force_and_tangent(flat.reshape(-1, 2))
        return f[free], K[free][:, free]

    flat[free] = newton(system, flat[free], tol)
    return flat.reshape(-1, 2)


def node_dofs(nodes: np.ndarray, components: tuple[int, ...] = (0, 1)) -> np.ndarray:
    """Flat dof indices of the given nodes and components (0 = x, 1 = y)."""
    return (2 * np.asarray(nodes)[:, None] + np.array(components)).reshape(-1)
