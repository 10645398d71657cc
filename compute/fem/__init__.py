"""Finite elements for deformable disks: total-Lagrangian, large strain, plane strain.

- ``material``: compressible neo-Hookean law (isochoric / volumetric split), numba kernels.
- ``elements``: T3 / T6 reference triangles, shape functions, quadrature rules.
- ``topology``: boundary loop of a disk mesh, exact element areas (shared with pre and post).
- ``body``: ``FEBody``, mass, internal force, consistent tangent, stresses, theta-scheme system.
"""

from .body import (
    VOLUMETRIC_FORMULATIONS,
    ElementStresses,
    FEBody,
    InvertedElementError,
    ThetaSystem,
)
from .elements import T3, T6, ElementType, QuadratureRule, element_type
from .topology import boundary_loop, signed_areas
from .material import (
    NeoHookean,
    cauchy_stress,
    isochoric_cauchy,
    isochoric_energy,
    isochoric_pk1,
    isochoric_pk1_tangent,
    volumetric_response,
    von_mises,
)

__all__ = [
    "FEBody",
    "ElementStresses",
    "ThetaSystem",
    "InvertedElementError",
    "boundary_loop",
    "signed_areas",
    "VOLUMETRIC_FORMULATIONS",
    "ElementType",
    "QuadratureRule",
    "T3",
    "T6",
    "element_type",
    "NeoHookean",
    "isochoric_energy",
    "isochoric_pk1",
    "isochoric_pk1_tangent",
    "volumetric_response",
    "isochoric_cauchy",
    "cauchy_stress",
    "von_mises",
]
