"""Stage 2 of the toolkit: reads a scene folder, runs NSCD(-FEM) time stepping, writes frames.

The public entry points are :func:`compute.run.run` and ``python -m compute SCENE --out OUT``.
Heavy modules (numba kernels, meshio) are imported where they are used.
"""

__all__ = ["SceneError", "SimulationError"]

from compute.errors import SceneError, SimulationError
