"""Fits of the paper's laws (post.models) to measured curves, and the Eq. 3 check.

Every fit returns a :class:`FitResult`: the free parameters and their standard errors (from the
covariance of scipy.optimize.curve_fit, scaled by the residual variance), the given parameters,
the fitted phi range and the RMS error. The laws with a log singularity at phi_max are fitted
with the bound phi_max > max(phi data), from an initial guess found on a grid of phi_max where the
linear amplitude (P0 or b) is solved exactly by least squares.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import curve_fit

from post import models

_GAPS = np.geomspace(1e-6, 1.0, 241)  # candidate phi_max - max(phi) for the initial guesses
_MAX_GAP = 2.0                         # upper bound of phi_max - max(phi)


@dataclass(frozen=True)
class FitResult:
    """A fitted law y = model(phi, **params, **fixed).

    ``rms`` is the RMS of (model - y) in the units of y, ``rms_relative`` the RMS of
    (model - y)/y over the points where y != 0; ``phi_range`` the (min, max) of the fitted phi.
    """

    model: Callable[..., np.ndarray]
    params: dict[str, float]
    stderr: dict[str, float]
    phi_range: tuple[float, float]
    rms: float
    rms_relative: float
    fixed: dict[str, float]

    def predict(self, phi: np.ndarray) -> np.ndarray:
        """The fitted law at phi (n,)."""
        return self.model(np.asarray(phi, dtype=float), **self.params, **self.fixed)


@dataclass(frozen=True)
class Check:
    """A measured curve against a prediction: ``relative_error`` (n,) = prediction/measured - 1."""

    prediction: np.ndarray
    relative_error: np.ndarray
    rms_relative: float


def _relative_rms(prediction: np.ndarray, y: np.ndarray) -> float:
    nonzero = y != 0
    return float(np.sqrt(np.mean((prediction[nonzero] / y[nonzero] - 1) ** 2))) if nonzero.any() else np.nan


def _curve_fit(model: Callable[..., np.ndarray], phi: np.ndarray, y: np.ndarray, names: tuple[str, ...],
               p0: list[float], bounds: tuple[list[float], list[float]], fixed: dict[str, float]) -> FitResult:
    """Least-squares fit of the parameters ``names`` of ``model`` from p0 within bounds."""

    def f(x: np.ndarray, *p: float) -> np.ndarray:
        return model(x, **dict(zip(names, p)), **fixed)

    p, cov = curve_fit(f, phi, y, p0=p0, bounds=bounds, x_scale="jac", ftol=1e-12, xtol=1e-12, gtol=1e-12)
    prediction = f(phi, *p)
    return FitResult(model=model, params=dict(zip(names, map(float, p))),
                     stderr=dict(zip(names, map(float, np.sqrt(np.diag(cov))))),
                     phi_range=(float(phi.min()), float(phi.max())),
                     rms=float(np.sqrt(np.mean((prediction - y) ** 2))),
                     rms_relative=_relative_rms(prediction, y), fixed=fixed)


def _as_curve(phi: np.ndarray, y: np.ndarray, n_params: int) -> tuple[np.ndarray, np.ndarray]:
    phi, y = np.asarray(phi, dtype=float).ravel(), np.asarray(y, dtype=float).ravel()
    if phi.shape != y.shape or len(phi) <= n_params or not (np.all(np.isfinite(phi)) and np.all(np.isfinite(y))):
        raise ValueError(f"need finite phi and y of equal length > {n_params}, got {phi.shape} and {y.shape}")
    return phi, y


def _fit_log_law(model: Callable[..., np.ndarray], phi: np.ndarray, y: np.ndarray, phi0: float,
                 names: tuple[str, str], fixed: dict[str, float]) -> FitResult:
    """Fit y = model(phi, scale, phi_max, **fixed), a log law of amplitude ``scale`` > 0 that
    diverges at phi_max > max(phi); ``names`` are the model's names of (scale, phi_max)."""
    phi, y = _as_curve(phi, y, 2)
    top = max(phi.max(), phi0)
    # y = scale g(phi; phi_max) is linear in scale: solve it exactly for each phi_max of a grid.
    grid = top + _GAPS[:, None]
    g = model(phi, **{names[0]: 1.0, names[1]: grid}, **fixed)                   # (n_gaps, n)
    scale = np.maximum((g @ y) / np.einsum("gn,gn->g", g, g), 1e-300)
    best = np.argmin(np.sum((scale[:, None] * g - y) ** 2, axis=1))
    return _curve_fit(model, phi, y, names, [scale[best], top + _GAPS[best]],
                      ([0.0, top + 1e-12], [np.inf, top + _MAX_GAP]), fixed)


def fit_platzer(phi: np.ndarray, pressure: np.ndarray, phi0: float) -> FitResult:
    """Platzer et al.: P = -P0 ln[(phi_max - phi)/(phi_max - phi0)], phi0 given, free P0, phi_max.

    phi, pressure (n,). Its bulk modulus is models.log_compaction_modulus(phi, P0, phi_max).
    """
    return _fit_log_law(models.platzer_pressure, phi, pressure, phi0, ("P0", "phi_max"), {"phi0": phi0})


def fit_single_particle(phi_p: np.ndarray, pressure_over_E: np.ndarray, phi_p0: float = np.pi / 4) -> FitResult:
    """Eq. 2: P_p/E = -b ln[(phi_p,max - phi_p)/(phi_p,max - phi_p,0)], free b, phi_p_max.

    phi_p, pressure_over_E (n,). K_p/E is models.log_compaction_modulus(phi_p, b, phi_p_max).
    """
    return _fit_log_law(models.single_particle_pressure, phi_p, pressure_over_E, phi_p0, ("b", "phi_p_max"),
                        {"phi_p0": phi_p0})


def fit_coordination(phi: np.ndarray, Z: np.ndarray, phi0: float, Z0: float) -> FitResult:
    """Z - Z0 = xi (phi - phi0)^alpha (paper Fig. 4), phi0 and Z0 given, free xi > 0, alpha in (0, 10).

    phi, Z (n,); only the points with phi > phi0 are fitted (phi_range says which). The initial
    guess is the straight line through the points with Z > Z0 in log-log axes.
    """
    phi, Z = _as_curve(phi, Z, 2)
    above = phi > phi0
    phi, Z = _as_curve(phi[above], Z[above], 2)
    usable = Z > Z0
    if usable.sum() >= 2:
        alpha, log_xi = np.polyfit(np.log(phi[usable] - phi0), np.log(Z[usable] - Z0), 1)
        p0 = [np.exp(log_xi), float(np.clip(alpha, 0.05, 5.0))]
    else:
        p0 = [1.0, 0.5]
    return _curve_fit(models.coordination_law, phi, Z, ("xi", "alpha"), p0, ([0.0, 0.0], [np.inf, 10.0]),
                      {"phi0": phi0, "Z0": Z0})


def fit_eq5(phi: np.ndarray, pressure_over_E: np.ndarray, b: float, xi: float, alpha: float, Z0: float,
            phi0: float) -> FitResult:
    """Eq. 5 with only phi_max free (b from Eq. 2, xi and alpha from Fig. 4, Z0 and phi0 given).

    phi, pressure_over_E (n,). ``rms_relative`` is the relative error of Eq. 5 on the data.
    """
    phi, y = _as_curve(phi, pressure_over_E, 1)
    fixed = {"b": b, "xi": xi, "alpha": alpha, "Z0": Z0, "phi0": phi0}
    top = max(phi.max(), phi0)
    ssr = np.sum((models.eq5_pressure(phi, top + _GAPS[:, None], **fixed) - y) ** 2, axis=1)
    return _curve_fit(models.eq5_pressure, phi, y, ("phi_max",), [top + _GAPS[int(np.argmin(ssr))]],
                      ([top + 1e-12], [top + _MAX_GAP]), fixed)


def eq3_check(phi: np.ndarray, K_over_E: np.ndarray, Z: np.ndarray, b: float, phi_p_max: float) -> Check:
    """Eq. 3: the measured K/E against (Z phi / 2 pi) K_p(phi)/E at equal phi; phi, K_over_E, Z (n,)."""
    K = np.asarray(K_over_E, dtype=float)
    prediction = models.eq3_bulk_modulus(np.asarray(phi, dtype=float), np.asarray(Z, dtype=float), b, phi_p_max)
    return Check(prediction=prediction, relative_error=prediction / K - 1,
                 rms_relative=_relative_rms(prediction, K))
