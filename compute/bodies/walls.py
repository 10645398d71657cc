"""The four walls: driving forces (pressure × current length) and optional inertial damping.

Wall w ∈ {0: xmin, 1: xmax, 2: ymin, 3: ymax} has one dof, its position s_w, moving along
+x (w = 0, 1) or +y (w = 2, 3). Under pressure control the wall is pushed inwards by
F_w = ± P L_w with L_w the current length of the wall (the box's other side).

Quasi-static control (the paper keeps the inertial number I ≪ 1e-4): optionally a viscous
force -c ṡ_w with c chosen so that a free wall would reach the terminal speed that gives the
target inertial number I* = ε̇ ⟨d⟩ √(ρ/P):  c = P L_w / (I* L_w √(P/ρ) / ⟨d⟩). The force
vanishes at rest, so it changes no equilibrium. Integrated with the θ-scheme:
(m + θ h c)(v⁺ - v⁻) = h (F - c v⁻) + r.

That coefficient does not grow with the packing, whose breathing mode does: with the walls
moving in by δ and the particles' velocity growing linearly from the centre, the mode has per
wall the mass m_w + M/6 (M the particles' mass) and the stiffness 4K (K the packing's bulk
modulus, ΔP = K ΔA/A), so its critical damping is 2 √(4 K (m_w + M/6)), and a large packing rings
for hundreds of steps after every pressure step. A stage's coefficient is therefore at least ζ
times that critical damping (``damping_ratio`` ζ, :func:`breathing_damping`), with K the
packing's modulus at the stage's pressure estimated from the equilibrated states so far
(:func:`stage_bulk_modulus`): the secant moduli of the last two intervals, read as a power law
of P and extrapolated to the stage's pressure. Why: beyond jamming K grows steeply with P, and
the last secant alone, the modulus halfway through the last stage, lags the modulus at the new
pressure by a factor that grows with P; damped from it, the stages P/E ≥ 0.3 of 1500-disk
mixtures rang for several periods, at a fraction of ζ, and their ringing was most of their steps
(benchmarks/results/wall_damping_n1500.md).
"""

from __future__ import annotations

import numpy as np

from compute.bodies.step_records import LinearStep

INWARD = np.array([1.0, -1.0, 1.0, -1.0])
MAX_EXPONENT = 2.0  # of the power law K ∝ P^α that stage_bulk_modulus extrapolates


class Walls:
    """The four walls as a body group: dofs ``dof0 + (0..3)`` = positions (xmin, xmax, ymin,
    ymax); ``mass`` of each wall; ``control`` "pressure" | "velocity"; ``damping`` the target
    inertial number of the viscous damping (0: none); ``density``, ``diameter`` of the
    particles (for the damping's time scale). ``held`` (4,) bool: walls kept at rest whatever
    the control (zero velocity and compliance). ``stage_damping`` the stage's least viscous
    coefficient (:func:`breathing_damping`, set by the loading program; 0: none)."""

    kind = "wall"
    nonlinear = False
    ids = np.array([-1, -2, -3, -4])

    def __init__(self, bounds, mass: float, control: str, damping: float, density: float, diameter: float,
                 dof0: int):
        self.initial_bounds = np.asarray(bounds, float)
        self.mass, self.control, self.damping = mass, control, damping
        self.density, self.diameter = density, diameter
        self.dof0 = dof0
        self.dofs = slice(dof0, dof0 + 4)
        self.held = np.zeros(4, bool)
        self.stage_damping = 0.0

    def __len__(self) -> int:
        return 4

    def bounds(self, q: np.ndarray) -> np.ndarray:
        """Box (xmin, xmax, ymin, ymax) (4,), a view of q."""
        return q[self.dofs]

    def initial(self, q: np.ndarray) -> None:
        q[self.dofs] = self.initial_bounds

    # --- the step -----------------------------------------------------------------------
    def begin_step(self, q, v, h, theta, load) -> LinearStep:
        """Free velocity and compliance 1 / m̂ of the walls for this step (module docstring)."""
        if self.control == "velocity":
            v_free = INWARD * load.wall_speed
            inverse = np.zeros(4)
        else:
            b, vw = self.bounds(q), v[self.dofs]
            force = pressure_forces(b, load.pressure)
            c = np.maximum(damping_coefficients(b, load.pressure, self.damping, self.density, self.diameter),
                           self.stage_damping)
            m_hat = self.mass + theta * h * c
            v_free = vw + h * (force - c * vw) / m_hat
            inverse = 1.0 / m_hat
        return LinearStep(np.arange(self.dofs.start, self.dofs.stop), np.where(self.held, 0.0, v_free),
                          np.where(self.held, 0.0, inverse))

    def kinetic_energy(self, v) -> float:
        return float(0.5 * self.mass * np.sum(v[self.dofs] ** 2))


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


def secant_bulk_modulus(pressures, areas) -> float:
    """Secant bulk modulus K = ΔP / ln(A_a / A_b) between the last two of the equilibrated
    states (``pressures`` (n,), box ``areas`` (n,)); 0 with fewer than two, or when the box did
    not shrink under a larger pressure (no elastic response to read)."""
    if len(pressures) < 2:
        return 0.0
    dp, shrink = pressures[-1] - pressures[-2], np.log(areas[-2] / areas[-1])
    return float(dp / shrink) if dp > 0.0 and shrink > 0.0 else 0.0


def stage_bulk_modulus(pressures, areas, pressure: float) -> float:
    """The packing's bulk modulus at ``pressure`` estimated from its equilibrated states
    (``pressures`` (n,), increasing, and box ``areas`` (n,)): the secant moduli K_a, K_b of the
    last two intervals (:func:`secant_bulk_modulus`) taken as a power law K ∝ P^α through the
    intervals' geometric-mean pressures P̄_a, P̄_b, α = ln(K_b / K_a) / ln(P̄_b / P̄_a) kept within
    [0, ``MAX_EXPONENT``] (K does not soften under compaction; a steeper law is not extrapolated
    from two noisy secants), evaluated at ``pressure``: K_b (``pressure`` / P̄_b)^α. The last
    secant alone where there is no earlier interval of positive pressures or a secant is 0. For
    log-spaced pressures and an exact power law this is the tangent modulus at ``pressure`` within
    a few per cent (the secant of an interval against the tangent at its geometric mean)."""
    k_b = secant_bulk_modulus(pressures, areas)
    if len(pressures) < 3 or pressures[-3] <= 0.0 or k_b <= 0.0:
        return k_b
    k_a = secant_bulk_modulus(pressures[:-1], areas[:-1])
    if k_a <= 0.0:
        return k_b
    p_b, p_a = np.sqrt(pressures[-1] * pressures[-2]), np.sqrt(pressures[-2] * pressures[-3])
    alpha = float(np.clip(np.log(k_b / k_a) / np.log(p_b / p_a), 0.0, MAX_EXPONENT))
    return float(k_b * (pressure / p_b) ** alpha)


def breathing_damping(ratio: float, modulus: float, particle_mass: float, wall_mass: float) -> float:
    """Viscous coefficient ζ 2 √(4 K (m_w + M/6)) of each wall: ``ratio`` ζ times the critical
    damping of the packing's breathing mode (module docstring) for bulk ``modulus`` K, particles'
    mass M and wall mass m_w."""
    return ratio * 2.0 * np.sqrt(4.0 * modulus * (wall_mass + particle_mass / 6.0))


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
