"""The compaction laws of the paper and their bulk moduli, as pure functions of phi (arrays (n,)).

Every bulk modulus here is K = dP/d eps_v with eps_v = -ln(phi_0/phi), i.e. K = phi dP/dphi.
Pressures and moduli of Eqs. 2, 3 and 5 are in units of the Young modulus E.
"""

from __future__ import annotations

import numpy as np


def log_compaction(phi: np.ndarray, scale: float, phi_max: float, phi0: float) -> np.ndarray:
    """P = -scale ln[(phi_max - phi)/(phi_max - phi0)]: the law of Platzer et al. (scale = P0) and of
    Eq. 2 (scale = b, P = P_p/E). Broadcasts over its arguments."""
    return -scale * np.log((phi_max - phi) / (phi_max - phi0))


def platzer_pressure(phi: np.ndarray, P0: float, phi_max: float, phi0: float) -> np.ndarray:
    """Platzer et al. (paper Sec. 2, Fig. 2): P = -P0 ln[(phi_max - phi)/(phi_max - phi0)]."""
    return log_compaction(phi, P0, phi_max, phi0)


def single_particle_pressure(phi_p: np.ndarray, b: float, phi_p_max: float,
                             phi_p0: float = np.pi / 4) -> np.ndarray:
    """Eq. 2: P_p/E = -b ln[(phi_p,max - phi_p)/(phi_p,max - phi_p,0)] (paper Fig. 5)."""
    return log_compaction(phi_p, b, phi_p_max, phi_p0)


def log_compaction_modulus(phi: np.ndarray, scale: float, phi_max: float) -> np.ndarray:
    """K = phi dP/dphi = scale phi / (phi_max - phi) of :func:`log_compaction`: the bulk modulus of
    Platzer et al. (scale = P0) and K_p/E of Eq. 2 (scale = b)."""
    return scale * phi / (phi_max - phi)


def coordination_law(phi: np.ndarray, xi: float, alpha: float, phi0: float, Z0: float) -> np.ndarray:
    """Z = Z0 + xi (phi - phi0)^alpha above jamming (paper Sec. 3, Fig. 4); Z0 below phi0."""
    return Z0 + xi * np.clip(phi - phi0, 0.0, None) ** alpha


def eq5_pressure(phi: np.ndarray, phi_max: float, b: float, xi: float, alpha: float, Z0: float,
                 phi0: float) -> np.ndarray:
    """Eq. 5: P/E = -(b phi / 2 pi) {Z0 + xi (phi - phi0)^alpha} ln[(phi_max - phi)/(phi_max - phi0)],
    i.e. Eq. 4, P = (Z phi / 2 pi) P_p, with Z from the coordination law and P_p from Eq. 2."""
    return phi / (2 * np.pi) * coordination_law(phi, xi, alpha, phi0, Z0) * log_compaction(phi, b, phi_max, phi0)


def eq3_bulk_modulus(phi: np.ndarray, Z: np.ndarray, b: float, phi_p_max: float) -> np.ndarray:
    """Eq. 3: K/E = (Z phi / 2 pi) K_p(phi)/E, K_p of the single particle (Eq. 2) at phi_p = phi."""
    return Z * phi / (2 * np.pi) * log_compaction_modulus(phi, b, phi_p_max)
