"""The figure helpers write PNGs; the pyvista helper fails cleanly without a backend."""

from __future__ import annotations

import io

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


# --- Fig. 1: soft disks coloured by their pressure --------------------------------------------

E, NU = 2.5, 0.495  # E != 1, so that the colours are p/E and not p


def dilation_pressure_over_E(stretch: float) -> float:
    """p/E of a neo-Hookean disk dilated uniformly in its plane, x = c + stretch (X - c), derived by
    hand from the law of compute/fem/material.py (plane strain, W = mu/2 (J^-2/3 I1 - 3) + U(J),
    U = kappa/4 (J^2 - 1 - 2 ln J), mu = E/(2(1 + nu)), kappa = E/(3(1 - 2 nu))):

    F = stretch I (2x2), F3 = diag(stretch, stretch, 1), J = stretch^2, b3 = diag(J, J, 1),
    I1 = 2J + 1; sigma = mu J^(-5/3) (b3 - I1/3 I3) + U'(J) I3 with U'(J) = kappa/2 (J - 1/J), so
    sigma_xx = sigma_yy = mu J^(-5/3) (J - 1)/3 + kappa/2 (J - 1/J). The isochoric part does not
    vanish: the out-of-plane stretch stays 1, so an in-plane dilation is not a 3D one (its
    deviator (J - 1)/3 diag(1, 1, -2) has in-plane components). p = -(sigma_xx + sigma_yy)/2."""
    J = stretch**2
    mu, kappa = E / (2 * (1 + NU)), E / (3 * (1 - 2 * NU))
    return -(mu * J ** (-5 / 3) * (J - 1) / 3 + kappa / 2 * (J - 1 / J)) / E


def _dilated_disk_frame(stretches: dict[str, float]):
    """A frame of a rigid disk (body 0) and one fan-meshed soft disk per element type (bodies 1,
    2, ...), each dilated by its stretch, whose cell pressures are the finite-element stresses of
    compute (FEBody.element_stresses), as compute writes them in the frames."""
    from compute.fem.body import FEBody
    from compute.fem.material import NeoHookean
    from post.frames import Bodies, Frame, FrameContacts, FrameRecord, MeshBlock, Walls
    from tests.post.synthetic import disk_fan

    material = NeoHookean(E, NU, 1.0)
    points, meshes = [np.zeros((1, 2))], []
    for body, (element, stretch) in enumerate(stretches.items(), start=1):
        centre = np.array([1.2 * body, 0.0])
        X, cells = disk_fan(centre, 0.5, 12, element)
        x = centre + stretch * (X - centre)
        pressure = FEBody(X, cells, element, material, "standard").element_stresses(x).pressure
        offset = sum(len(p) for p in points)
        points.append(x)
        meshes.append(MeshBlock(element, cells + offset, np.full(len(cells), body), pressure))
    n = 1 + len(stretches)
    bodies = Bodies(points=np.vstack(points), radius=np.full(n, 0.5), rigid=np.arange(n) == 0,
                    rigid_ids=np.array([0]), rigid_centres=np.zeros((1, 2)), meshes=tuple(meshes))
    pairs = np.arange(n - 1)
    centres = 1.2 * np.stack([np.arange(n), np.zeros(n)], axis=1)
    contacts = FrameContacts(body_i=pairs, body_j=pairs + 1, force=np.zeros((n - 1, 2)), fn=np.arange(1.0, n),
                             branch=np.diff(centres, axis=0), segments=np.stack([centres[:-1], centres[1:]], axis=1))
    walls = Walls(position=np.array([-0.6, 1.2 * n - 0.6, -0.6, 0.6]), length=np.ones(4), force=np.zeros(4))
    return Frame(FrameRecord(0, 0.0, 0, 0, 0.01 * E, True, (-0.6, 1.2 * n - 0.6, -0.6, 0.6)), bodies, contacts, walls)


def test_soft_disks_are_coloured_by_their_analytic_pressure_over_E():
    """A T3 disk compressed by 3 % and a T6 disk dilated by 2 %: each is filled with one colour,
    the viridis colour of the p/E of the neo-Hookean law under that dilation; the rigid disk is
    grey; the force network is not drawn unless asked, and thin when it is."""
    from matplotlib import colormaps
    from matplotlib.collections import LineCollection, PatchCollection, PolyCollection

    stretches = {"T3": 0.97, "T6": 1.02}
    frame = _dilated_disk_frame(stretches)
    figure, axes = plots.new_figure()
    mappable = plots.draw_frame(axes[0, 0], frame, young=E)
    figure.savefig(io.BytesIO(), format="png")  # drawing maps the values to the colours
    soft = [c for c in axes[0, 0].collections if isinstance(c, PolyCollection)]
    assert len(soft) == 2
    expected = [dilation_pressure_over_E(s) for s in stretches.values()]
    assert expected[0] > 0 > expected[1]  # compressed: positive pressure; dilated: negative
    for collection, p_over_E in zip(soft, expected):
        values = np.asarray(collection.get_array())
        np.testing.assert_allclose(values, p_over_E, rtol=1e-9)
        np.testing.assert_allclose(collection.get_facecolor(), colormaps["viridis"](mappable.norm(values)), atol=1e-12)
    assert mappable.norm.vmin == pytest.approx(expected[1]) and mappable.norm.vmax == pytest.approx(expected[0])
    assert mappable.colorbar.ax.get_ylabel() == "p/E"
    rigid = next(c for c in axes[0, 0].collections if isinstance(c, PatchCollection))
    np.testing.assert_allclose(rigid.get_facecolor()[0], (0.7, 0.7, 0.7, 1.0))
    assert not any(isinstance(c, LineCollection) for c in axes[0, 0].collections)

    figure, axes = plots.new_figure()
    plots.draw_frame(axes[0, 0], frame, young=E, forces=True, max_width=0.8)
    lines = [c for c in axes[0, 0].collections if isinstance(c, LineCollection)]
    assert len(lines) == 1 and max(lines[0].get_linewidths()) == pytest.approx(0.8)


def test_a_body_pressure_is_the_area_weighted_mean_of_its_cells():
    """Cells of hand-known areas: T3 triangles of areas 1 and 3; a T6 triangle with straight edges
    (area 2) and one whose edge 01 bulges by 0.5 (area 2 + 4/3 x 0.5, Archimedes' parabolic
    segment); a body without cells (rigid) has none."""
    from post.measures import body_pressures

    points = np.array([[0, 0], [1, 0], [0, 2], [4, 0], [1, 2],             # T3: 0-1-2 (area 1), 1-3-4 (area 3)
                       [0, 0], [2, 0], [0, 2], [1, -0.5], [1, 1], [0, 1],   # T6, edge 01 bulging
                       [0, 0], [0, -2], [2, 0], [0, -1], [1, -1], [1, 0]],  # T6, straight (area 2)
                      dtype=float)
    t3 = (np.array([[0, 1, 2], [1, 3, 4]]), np.array([0, 0]), np.array([4.0, 0.0]))
    t6 = (np.array([[5, 6, 7, 8, 9, 10], [11, 12, 13, 14, 15, 16]]), np.array([1, 1]), np.array([3.0, -1.0]))
    p = body_pressures(3, points, [t3, t6])
    np.testing.assert_allclose(p[:2], [(4 * 1 + 0 * 3) / 4, (3 * 8 / 3 - 1 * 2) / (8 / 3 + 2)])
    assert np.isnan(p[2])


def test_saved_png_is_a_palette_close_to_the_rendering(tmp_path):
    """save_figure writes a PNG as a 256-colour palette whose pixels stay within a few levels of
    matplotlib's own full-colour rendering of the same figure (a smooth viridis field, the
    hardest case for a palette), and other formats as matplotlib writes them."""
    from PIL import Image

    figure, axes = plots.new_figure(1, 1)
    x, y = np.meshgrid(np.linspace(0.0, 1.0, 300), np.linspace(0.0, 1.0, 200))
    axes[0, 0].imshow(np.sin(6 * x) * np.cos(4 * y) + x, cmap="viridis")
    path = plots.save_figure(figure, tmp_path / "field.png")
    figure.savefig(tmp_path / "direct.png", dpi=150)
    with Image.open(path) as saved, Image.open(tmp_path / "direct.png") as direct:
        assert saved.mode == "P"
        ours = np.asarray(saved.convert("RGB"), dtype=float)
        theirs = np.asarray(direct.convert("RGB"), dtype=float)
    assert ours.shape == theirs.shape
    difference = np.abs(ours - theirs)
    assert difference.mean() < 2.0 and np.percentile(difference, 99) < 12.0
    assert (tmp_path / "direct.png").stat().st_size > path.stat().st_size
    assert plots.save_figure(figure, tmp_path / "field.pdf").read_bytes()[:4] == b"%PDF"
