"""Optional rendering of a bodies frame with pyvista, off screen.

Headless VTK needs ``VTK_DEFAULT_OPENGL_WINDOW=vtkEGLRenderWindow`` set before pyvista is imported
and ``pyvista.OFF_SCREEN = True``. With no display, no EGL and no OSMesa VTK segfaults instead of
raising, so a tiny scene is first rendered in a subprocess; if that fails, :class:`RenderError`.
Nothing else in post depends on this module.
"""

from __future__ import annotations

import functools
import os
import subprocess
import sys
from pathlib import Path

from post.errors import RenderError

_WINDOW_VARIABLE, _WINDOW_CLASS = "VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow"
_PROBE = """
import pyvista
pyvista.OFF_SCREEN = True
plotter = pyvista.Plotter(off_screen=True, window_size=(32, 32))
plotter.add_mesh(pyvista.Sphere())
plotter.screenshot(return_img=True)
plotter.close()
"""


@functools.cache
def render_available() -> bool:
    """Whether VTK can render off screen here (probed once per process, in a subprocess)."""
    env = dict(os.environ)
    env.setdefault(_WINDOW_VARIABLE, _WINDOW_CLASS)
    try:
        probe = subprocess.run([sys.executable, "-c", _PROBE], env=env, capture_output=True, timeout=120)
    except subprocess.TimeoutExpired:
        return False
    return probe.returncode == 0


def render_bodies(bodies_vtu: str | Path, png: str | Path, scalars: str = "von_mises",
                  window_size: tuple[int, int] = (1200, 1200)) -> Path:
    """Render a ``bodies_NNNNN.vtu`` frame to png: rigid disks as grey discs of their radius,
    deformable meshes coloured by the cell field ``scalars``; viewed along z."""
    if not render_available():
        raise RenderError("no usable off-screen OpenGL backend for VTK (needs EGL, OSMesa or a display; "
                          "on Debian: apt-get install libegl1); use post.plots for matplotlib figures")
    os.environ.setdefault(_WINDOW_VARIABLE, _WINDOW_CLASS)
    import numpy as np
    import pyvista

    pyvista.OFF_SCREEN = True
    mesh = pyvista.read(bodies_vtu)
    vertex = mesh.celltypes == pyvista.CellType.VERTEX
    plotter = pyvista.Plotter(off_screen=True, window_size=window_size)
    if vertex.any():
        centres = pyvista.PolyData(mesh.points[mesh.cells_dict[pyvista.CellType.VERTEX][:, 0]])
        centres["radius"] = mesh.cell_data["radius"][vertex]
        discs = centres.glyph(geom=pyvista.Disc(inner=0.0, outer=1.0, c_res=48), scale="radius", orient=False)
        plotter.add_mesh(discs, color="lightgrey")
    if (~vertex).any():
        plotter.add_mesh(mesh.extract_cells(np.flatnonzero(~vertex)), scalars=scalars, preference="cell",
                         show_edges=True, edge_color="grey", line_width=0.2)
    plotter.view_xy()
    png = Path(png)
    png.parent.mkdir(parents=True, exist_ok=True)
    plotter.screenshot(png)
    plotter.close()
    return png
