"""Reference triangles: shape functions, quadrature rules and edge topology.

Reference triangle: corners (0, 0), (1, 0), (0, 1); area 1/2 (quadrature weights sum to 1/2).
Barycentric coordinates L0 = 1 - xi - eta, L1 = xi, L2 = eta.

- ``T3``: linear triangle, N_a = L_a.
- ``T6``: quadratic triangle, node order of gmsh / meshio ``triangle6``: corners 0, 1, 2, then the
  midside nodes of edges 0-1, 1-2, 2-0. N_a = L_a (2 L_a - 1) at corners, 4 L_a L_b at midsides.

Each element carries two rules: ``stiffness_rule`` (1 point, degree 1 for T3; 3 points, degree 2
for T6: exact for the area and for the T6 nodal volume gradients, whose integrands are of degree 2)
and ``mass_rule`` (3 points, degree 2 for T3; 6 points, degree 4 for T6: exact for the consistent
mass matrix of straight-sided elements).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

__all__ = ["QuadratureRule", "ElementType", "T3", "T6", "element_type"]


@dataclass(frozen=True)
class QuadratureRule:
    """Quadrature on the reference triangle.

    points: (n_q, 2) reference coordinates (xi, eta); weights: (n_q,), summing to 1/2;
    degree: polynomials up to this total degree are integrated exactly.
    """

    points: np.ndarray
    weights: np.ndarray
    degree: int


def _symmetric_rule(orbits: list[tuple[float, float]], degree: int) -> QuadratureRule:
    """Rule from (a, w) orbits: points (a, a), (1 - 2a, a), (a, 1 - 2a) of weight w / 2 each."""
    points, weights = [], []
    for a, w in orbits:
        points += [(a, a), (1.0 - 2.0 * a, a), (a, 1.0 - 2.0 * a)]
        weights += [0.5 * w] * 3
    return QuadratureRule(np.array(points), np.array(weights), degree)


CENTROID_RULE = QuadratureRule(np.array([[1.0 / 3.0, 1.0 / 3.0]]), np.array([0.5]), 1)
STRANG_FIX_3 = _symmetric_rule([(1.0 / 6.0, 1.0 / 3.0)], 2)
DUNAVANT_6 = _symmetric_rule(
    [
        (0.44594849091596488632, 0.22338158967801146570),
        (0.09157621350977074346, 0.10995174365532186764),
    ],
    4,
)


def _t3_basis(xi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """T3 shape functions at points xi (m, 2): N (m, 3) and dN/dxi (m, 3, 2)."""
    m = xi.shape[0]
    n = np.column_stack([1.0 - xi[:, 0] - xi[:, 1], xi[:, 0], xi[:, 1]])
    dn = np.broadcast_to(np.array([[-1.0, -1.0], [1.0, 0.0], [0.0, 1.0]]), (m, 3, 2)).copy()
    return n, dn


def _t6_basis(xi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """T6 shape functions at points xi (m, 2): N (m, 6) and dN/dxi (m, 6, 2)."""
    lam, dlam = _t3_basis(xi)  # barycentric coordinates and their (constant) gradients
    pairs = ((0, 1), (1, 2), (2, 0))
    n = np.empty((xi.shape[0], 6))
    dn = np.empty((xi.shape[0], 6, 2))
    for a in range(3):
        n[:, a] = lam[:, a] * (2.0 * lam[:, a] - 1.0)
        dn[:, a] = (4.0 * lam[:, a] - 1.0)[:, None] * dlam[:, a]
    for m, (a, b) in enumerate(pairs, start=3):
        n[:, m] = 4.0 * lam[:, a] * lam[:, b]
        dn[:, m] = 4.0 * (lam[:, a, None] * dlam[:, b] + lam[:, b, None] * dlam[:, a])
    return n, dn


@dataclass(frozen=True)
class ElementType:
    """An isoparametric triangle.

    name: "T3" | "T6"; n_nodes: nodes per element (3 | 6);
    basis: xi (m, 2) -> (N (m, n_nodes), dN/dxi (m, n_nodes, 2));
    edges: (3, 2 | 3) local node indices along each edge, counter-clockwise for a CCW element
    (first and last entries are the corners, the middle one the midside node for T6);
    nodes: (n_nodes, 2) reference coordinates of the nodes;
    stiffness_rule, mass_rule: see the module docstring.
    """

    name: str
    n_nodes: int
    basis: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]
    edges: np.ndarray
    nodes: np.ndarray
    stiffness_rule: QuadratureRule
    mass_rule: QuadratureRule


_CORNERS = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])

T3 = ElementType(
    name="T3",
    n_nodes=3,
    basis=_t3_basis,
    edges=np.array([[0, 1], [1, 2], [2, 0]]),
    nodes=_CORNERS,
    stiffness_rule=CENTROID_RULE,
    mass_rule=STRANG_FIX_3,
)

T6 = ElementType(
    name="T6",
    n_nodes=6,
    basis=_t6_basis,
    edges=np.array([[0, 3, 1], [1, 4, 2], [2, 5, 0]]),
    nodes=np.vstack([_CORNERS, 0.5 * (_CORNERS + np.roll(_CORNERS, -1, axis=0))]),
    stiffness_rule=STRANG_FIX_3,
    mass_rule=DUNAVANT_6,
)


def element_type(name: str) -> ElementType:
    """The element called ``name`` ("T3" or "T6"); ValueError otherwise."""
    types = {"T3": T3, "T6": T6}
    if name not in types:
        raise ValueError(f"element type must be one of {sorted(types)}, got {name!r}")
    return types[name]
