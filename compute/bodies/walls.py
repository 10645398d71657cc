"""The four walls: driving forces (pressure × current length) and optional inertial damping.

Wall w ∈ {0: xmin, 1: xmax, 2: ymin, 3: ymax} has one dof, its position s_w, moving along
+x (w = 0, 1) or +y (w = 2, 3). Under pressure control the wall is pushed inwards by
F_w = ± P L_w with L_w the current length of the wall (the box's other side).

Quasi-static control (the paper keeps the inertial number I ≪ 1e-4): optionally a viscous
force -c ṡ_w with c chosen so that a free wall would reach the terminal speed that gives the
target inertial number I* = ε̇ ⟨d⟩ √(ρ/P):  c = P L_w / (I* L_w √(P/ρ) / ⟨d⟩). The force
vanishes at rest, so it changes no equilibrium. Integrated with the θ-scheme:
(m + θ h c)(v⁺ - v⁻) = h (F - c v⁻) + r.
"""

from __future__ import annotations

import numpy as np

INWARD = np.array([1.0, -1.0, 1.0, -1.0])


def wall_lengths(bounds: np.ndarray) -> np.ndarray:
    """Current lengths (4,) of the walls of the box bounds (xmin, xmax, ymin, ymax)."""
    lx, ly = bounds[1] - bounds[0], bounds[3] - bounds[2]
    return np.array([ly, ly, lx, lx])


def pressure_forces(bounds: np.ndarray, pressure: float) -> np.ndarray:
    """Imposed wall forces (4,) along each wall's dof axis."""
    return INWARD * pressure * wall_lengths(bounds)


def damping_coefficients(bounds: np.ndarray, pressure: float, inertial_number: float,
                         density: float, diameter: float) -> np.ndarray:
    """Viscous coefficients c_w (4,) giving the terminal speed of the target inertial number."""
    if inertial_number <= 0.0 or pressure <= 0.0:
        return np.zeros(4)
    lengths = wall_lengths(bounds)
    box = np.array([lengths[2], lengths[2], lengths[0], lengths[0]])  # size along the wall's axis
    speed = inertial_number * box * np.sqrt(pressure / density) / diameter
    return pressure * lengths / speed


def inertial_number(bounds: np.ndarray, wall_velocity: np.ndarray, pressure: float, density: float,
                    diameter: float) -> float:
    """I = ⟨d⟩ √(ρ/P) max(|ε̇_xx|, |ε̇_yy|) from the walls' strain rates, as the paper controls it.

    Particle velocities are left out on purpose: rattlers of a frictionless packing slide in
    their cages for ever without changing φ or the stress.
    """
    if pressure <= 0.0:
        return np.inf
    lx, ly = bounds[1] - bounds[0], bounds[3] - bounds[2]
    rate = max(abs(wall_velocity[1] - wall_velocity[0]) / lx, abs(wall_velocity[3] - wall_velocity[2]) / ly)
    return float(rate * diameter * np.sqrt(density / pressure))
