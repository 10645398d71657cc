r"""Compressible neo-Hookean law with a volumetric / isochoric split, in plane strain.

Plane strain, unit thickness: the in-plane deformation gradient F (2x2) is embedded as
F3 = diag(F, 1), so that

    J = det F,   C = F^T F,   I1 = tr C + 1   (first invariant of the 3D right Cauchy-Green tensor).

Strain energy per unit reference volume:

    W(F) = W_iso(F) + U(J),
    W_iso(F) = mu/2 (J^(-2/3) I1 - 3),
    U(J)     = kappa/4 (J^2 - 1 - 2 ln J),

with mu = E / (2 (1 + nu)) and kappa = E / (3 (1 - 2 nu)); for small strains the law reduces to
plane-strain linear elasticity with the Lamé constants (kappa - 2 mu / 3, mu).

Derived quantities (F^-T written G, all 2x2 except the Cauchy stress):

    P_iso = mu J^(-2/3) (F - I1/3 G)                                first Piola-Kirchhoff stress
    A_iso[i,J,k,L] = d P_iso[i,J] / d F[k,L]
        = mu J^(-2/3) [ d_ik d_JL - 2/3 (F_iJ G_kL + G_iJ F_kL)
                        + 2/9 I1 G_iJ G_kL + I1/3 G_iL G_kJ ]
    U'(J) = kappa/2 (J - 1/J),   U''(J) = kappa/2 (1 + 1/J^2)
    sigma = mu J^(-5/3) (b3 - I1/3 I3) + U'(J) I3,   b3 = F3 F3^T      (3x3 Cauchy stress)

The volumetric part is left to the caller through U, U', U'' so that an element can use the
pointwise J or a mean dilatation J-bar (see ``compute.fem.body``).

Inadmissible states: every function returns NaN (scalars) or NaN-filled arrays when J <= 0. It
never clamps; callers detect the NaN, or better test J beforehand (``FEBody`` does and raises).

Array-valued functions take optional ``out`` buffers (numpy style) so that element loops do not
allocate per quadrature point. Kernels use IEEE arithmetic (numba ``error_model="numpy"``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

__all__ = [
    "NeoHookean",
    "isochoric_energy",
    "isochoric_pk1",
    "isochoric_pk1_tangent",
    "volumetric_response",
    "isochoric_cauchy",
    "cauchy_stress",
    "von_mises",
]


@dataclass(frozen=True)
class NeoHookean:
    """Material constants: Young's modulus E > 0, Poisson ratio -1 < nu < 1/2, density > 0."""

    young: float
    poisson: float
    density: float

    def __post_init__(self) -> None:
        if not self.young > 0.0:
            raise ValueError(f"young must be > 0, got {self.young}")
        if not -1.0 < self.poisson < 0.5:
            raise ValueError(f"poisson must lie in (-1, 0.5), got {self.poisson}")
        if not self.density > 0.0:
            raise ValueError(f"density must be > 0, got {self.density}")

    @property
    def mu(self) -> float:
        """Shear modulus E / (2 (1 + nu))."""
        return self.young / (2.0 * (1.0 + self.poisson))

    @property
    def kappa(self) -> float:
        """Bulk modulus E / (3 (1 - 2 nu))."""
        return self.young / (3.0 * (1.0 - 2.0 * self.poisson))


@numba.njit(cache=True, error_model="numpy")
def _invariants(F: np.ndarray) -> tuple[float, float, tuple]:
    """J = det F, I1 = |F|^2 + 1 and G = F^-T (nested tuples, G[i][j]) of F (2, 2); J > 0."""
    J = F[0, 0] * F[1, 1] - F[0, 1] * F[1, 0]
    G = ((F[1, 1] / J, -F[1, 0] / J), (-F[0, 1] / J, F[0, 0] / J))
    I1 = F[0, 0] ** 2 + F[0, 1] ** 2 + F[1, 0] ** 2 + F[1, 1] ** 2 + 1.0
    return J, I1, G


@numba.njit(cache=True, error_model="numpy")
def isochoric_energy(F: np.ndarray, mu: float) -> float:
    """W_iso(F) = mu/2 (J^(-2/3) I1 - 3) for F (2, 2); NaN if J <= 0."""
    J = F[0, 0] * F[1, 1] - F[0, 1] * F[1, 0]
    if J <= 0.0:
        return np.nan
    I1 = F[0, 0] ** 2 + F[0, 1] ** 2 + F[1, 0] ** 2 + F[1, 1] ** 2 + 1.0
    return 0.5 * mu * (J ** (-2.0 / 3.0) * I1 - 3.0)


@numba.njit(cache=True, error_model="numpy")
def isochoric_pk1(F: np.ndarray, mu: float, out: np.ndarray | None = None) -> np.ndarray:
    """P_iso = dW_iso/dF, (2, 2), for F (2, 2), written to ``out`` if given; NaN if J <= 0."""
    if out is None:
        out = np.empty((2, 2))
    if F[0, 0] * F[1, 1] - F[0, 1] * F[1, 0] <= 0.0:
        out[:] = np.nan
        return out
    J, I1, G = _invariants(F)
    c = mu * J ** (-2.0 / 3.0)
    for i in range(2):
        for j in range(2):
            out[i, j] = c * (F[i, j] - I1 / 3.0 * G[i][j])
    return out


@numba.njit(cache=True, error_model="numpy")
def isochoric_pk1_tangent(
    F: np.ndarray, mu: float, P: np.ndarray | None = None, A: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """P_iso (2, 2) and A_iso[i, J, k, L] = dP_iso[i, J]/dF[k, L] (2, 2, 2, 2) for F (2, 2).

    Written to ``P`` and ``A`` if given; NaN-filled if J <= 0.
    """
    P = isochoric_pk1(F, mu, P)
    if A is None:
        A = np.empty((2, 2, 2, 2))
    if F[0, 0] * F[1, 1] - F[0, 1] * F[1, 0] <= 0.0:
        A[:] = np.nan
        return P, A
    J, I1, G = _invariants(F)
    c = mu * J ** (-2.0 / 3.0)
    for i in range(2):
        for j in range(2):
            for k in range(2):
                for m in range(2):
                    A[i, j, k, m] = c * (
                        (1.0 if (i == k and j == m) else 0.0)
                        - 2.0 / 3.0 * (F[i, j] * G[k][m] + G[i][j] * F[k, m])
                        + 2.0 / 9.0 * I1 * G[i][j] * G[k][m]
                        + I1 / 3.0 * G[i][m] * G[k][j]
                    )
    return P, A


@numba.njit(cache=True, error_model="numpy")
def volumetric_response(J: float, kappa: float) -> tuple[float, float, float]:
    """(U(J), U'(J), U''(J)) for U = kappa/4 (J^2 - 1 - 2 ln J); NaNs if J <= 0."""
    if J <= 0.0:
        return np.nan, np.nan, np.nan
    U = 0.25 * kappa * (J * J - 1.0 - 2.0 * np.log(J))
    return U, 0.5 * kappa * (J - 1.0 / J), 0.5 * kappa * (1.0 + 1.0 / (J * J))


@numba.njit(cache=True, error_model="numpy")
def isochoric_cauchy(F: np.ndarray, mu: float, out: np.ndarray | None = None) -> np.ndarray:
    """Isochoric Cauchy stress mu J^(-5/3) dev(b3), (3, 3), for F (2, 2), written to ``out``
    if given; NaN if J <= 0."""
    if out is None:
        out = np.empty((3, 3))
    J = F[0, 0] * F[1, 1] - F[0, 1] * F[1, 0]
    if J <= 0.0:
        out[:] = np.nan
        return out
    c = mu * J ** (-5.0 / 3.0)
    out[:] = 0.0
    for i in range(2):
        for j in range(2):
            out[i, j] = c * (F[i, 0] * F[j, 0] + F[i, 1] * F[j, 1])
    out[2, 2] = c
    third_trace = (out[0, 0] + out[1, 1] + out[2, 2]) / 3.0
    for i in range(3):
        out[i, i] -= third_trace
    return out


@numba.njit(cache=True, error_model="numpy")
def cauchy_stress(
    F: np.ndarray, mu: float, kappa: float, out: np.ndarray | None = None
) -> np.ndarray:
    """Full plane-strain Cauchy stress (3, 3), sigma_zz included, for F (2, 2), written to
    ``out`` if given; NaN if J <= 0."""
    out = isochoric_cauchy(F, mu, out)
    dU = volumetric_response(F[0, 0] * F[1, 1] - F[0, 1] * F[1, 0], kappa)[1]
    for i in range(3):
        out[i, i] += dU
    return out


@numba.njit(cache=True, error_model="numpy")
def von_mises(s: np.ndarray) -> float:
    """Von Mises equivalent stress sqrt(3/2 dev(s):dev(s)) of a symmetric (3, 3) stress."""
    return np.sqrt(
        0.5 * ((s[0, 0] - s[1, 1]) ** 2 + (s[1, 1] - s[2, 2]) ** 2 + (s[2, 2] - s[0, 0]) ** 2)
        + 3.0 * (s[0, 1] ** 2 + s[1, 2] ** 2 + s[2, 0] ** 2)
    )
