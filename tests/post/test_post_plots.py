"""The figure helpers write PNGs; the pyvista helper fails cleanly without a backend."""

from __future__ import annotations

import numpy as np
import pytest

from post import fits, models, plots, render
from post.errors import RenderError
from post.frames import frame_path, iter_frames

PHI0, Z0 = 0.811, 3.6


def test_force_chains_of_a_mixed_frame(mixed_lattice, tmp_path):
    frame = list(iter_frames(mixed_lattice))[-1]
    assert plots.force_chains_png(frame, tmp_path / "chains.png").stat().st_size > 0


def test_paper_figures_helpers(tmp_path):
    phi = np.linspace(0.815, 0.93, 10)
    fixed = {"b": 0.14, "xi": 5.1, "alpha": 0.5, "Z0": Z0, "phi0": PHI0}
    P = models.eq5_pressure(phi, 0.95, **fixed)
    platzer, eq5 = fits.fit_platzer(phi, P, PHI0), fits.fit_eq5(phi, P, **fixed)
    Z = models.coordination_law(phi, 5.1, 0.5, PHI0, Z0)
    phi_p = np.linspace(0.79, 0.97, 10)
    single = fits.fit_single_particle(phi_p, models.single_particle_pressure(phi_p, 0.14, 0.99))
    figure, axes = plots.new_figure(2, 2)
    plots.plot_compaction(axes[0, 0], P, phi, "kappa = 0.5", fits=[("Platzer", platzer, ":"), ("Eq. 5", eq5, "-")])
    K = models.log_compaction_modulus(phi, platzer.params["P0"], platzer.params["phi_max"])
    plots.plot_bulk_modulus(axes[0, 1], phi, K, "data",
                            predictions=[("Eq. 3", phi, models.eq3_bulk_modulus(phi, Z, 0.14, 0.99), "-")])
    law = fits.fit_coordination(phi, Z, PHI0, Z0)
    plots.plot_coordination(axes[1, 0], phi - PHI0, Z - Z0, "data",
                            laws=[("fit", law.params["xi"], law.params["alpha"], "--", "k")])
    plots.plot_single_particle(axes[1, 1], {"Ne = 92": (models.single_particle_pressure(phi_p, 0.14, 0.99), phi_p)},
                               fit=single)
    lines = {line.get_label(): line for ax in axes.ravel() for line in ax.get_lines()}
    assert {"kappa = 0.5", "Platzer", "Eq. 5", "data", "Eq. 3", "fit"} <= set(lines)
    x, y = lines["fit"].get_data()  # the coordination law drawn is the fitted one
    np.testing.assert_allclose(y, 5.1 * x**0.5, rtol=1e-6)
    assert plots.save_figure(figure, tmp_path / "figs" / "paper.png").stat().st_size > 0


def test_render_without_backend_raises(monkeypatch, lattice, tmp_path):
    monkeypatch.setattr(render, "render_available", lambda: False)
    with pytest.raises(RenderError, match="off-screen"):
        render.render_bodies(frame_path(lattice, "bodies", 0), tmp_path / "bodies.png")


@pytest.mark.slow
def test_render_when_a_backend_exists(mixed_lattice, tmp_path):
    if not render.render_available():
        pytest.skip("no off-screen OpenGL backend")
    png = render.render_bodies(frame_path(mixed_lattice, "bodies", 3), tmp_path / "bodies.png", scalars="pressure")
    assert png.stat().st_size > 0
