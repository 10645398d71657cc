"""Figures with matplotlib (Agg, no pyplot state): a frame as the paper's Fig. 1 (soft disks
coloured by their pressure, the force network optional), phi and Z against P, and helpers that
draw the paper's Figs. 2-5 on a given Axes so that the studies compose them.

matplotlib is imported inside the functions (its import is slow), never at package import.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from post import measures, rounding

if TYPE_CHECKING:
    from post.compaction import Compaction
    from post.fits import FitResult
    from post.frames import Frame

_T6_OUTLINE = [0, 3, 1, 4, 2, 5]  # T6 nodes around the element: corner, mid-side, corner, ...


def new_figure(nrows: int = 1, ncols: int = 1, size: tuple[float, float] = (5.0, 4.0)):
    """A figure (Agg canvas) and its (nrows, ncols) array of Axes."""
    from matplotlib.figure import Figure

    figure = Figure(figsize=(size[0] * ncols, size[1] * nrows), layout="constrained")
    return figure, figure.subplots(nrows, ncols, squeeze=False)


def save_figure(figure, path: str | Path, dpi: int = 150) -> Path:
    """Save figure as path (format from the suffix), creating the folder. A PNG is written with
    an adaptive palette of 256 colours (Pillow's median cut): a frame of a large packing, each
    disk its own shade, is several times smaller so, and the study folders that keep their
    figures stay small; the colours move by less than a palette step."""
    import io

    from PIL import Image

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.suffix.lower() != ".png":
        figure.savefig(path, dpi=dpi)
        return path
    rendered = io.BytesIO()
    figure.savefig(rendered, format="png", dpi=dpi)
    with Image.open(rendered) as image:
        image.convert("RGB").quantize(256, method=Image.Quantize.MEDIANCUT).save(path, optimize=True)
    return path


def draw_frame(ax, frame: Frame, young: float = 1.0, forces: bool = False, threshold: float = 1e-9,
               max_width: float = 1.0, norm=None):
    """Draw a frame like the paper's Fig. 1: the rigid disks grey, each deformable disk filled by
    its pressure over E (post.measures.body_pressures, the area-weighted mean of its cell
    pressures) on the continuous viridis scale ``norm`` (default: from min(0, lowest) to the
    frame's highest p/E) with a colorbar labelled p/E, and the box. With ``forces``, the active
    contacts (fn > threshold x mean fn) over it as thin segments between centres, of width
    proportional to fn, ``max_width`` points at the largest.

    Returns the ScalarMappable of the disks' colours (None when the frame has no deformable body).
    """
    from matplotlib.cm import ScalarMappable
    from matplotlib.collections import LineCollection, PatchCollection, PolyCollection
    from matplotlib.colors import Normalize
    from matplotlib.patches import Circle

    bodies, contacts = frame.bodies, frame.contacts
    radii = bodies.radius[bodies.rigid_ids]
    ax.add_collection(PatchCollection([Circle(c, r) for c, r in zip(bodies.rigid_centres, radii)],
                                      facecolor="0.7", edgecolor="0.35", linewidth=0.3))
    mappable = None
    if bodies.meshes:
        p_over_E = measures.body_pressures(bodies.n_bodies, bodies.points,
                                           [(m.cells, m.body, m.pressure) for m in bodies.meshes]) / young
        soft = p_over_E[~bodies.rigid]
        if norm is None:
            norm = Normalize(min(0.0, soft.min()), max(soft.max(), min(0.0, soft.min()) + 1e-300))
        mappable = ScalarMappable(norm, "viridis")
        for m in bodies.meshes:  # every cell of a body in the body's colour, edges included (no mesh lines)
            outline = m.cells[:, _T6_OUTLINE] if m.element == "T6" else m.cells
            ax.add_collection(PolyCollection(bodies.points[outline], array=p_over_E[m.body], cmap="viridis",
                                             norm=norm, edgecolors="face", linewidths=0.2))
        ax.figure.colorbar(mappable, ax=ax, label="p/E", shrink=0.8)
    active = measures.active_contacts(contacts.fn, threshold)
    if forces and active.any():
        fn = contacts.fn[active]
        ax.add_collection(LineCollection(contacts.segments[active], linewidths=max_width * fn / fn.max(),
                                         colors="k", zorder=3))
    left, right, bottom, top = frame.walls.position
    ax.plot([left, right, right, left, left], [bottom, bottom, top, top, bottom], color="k", linewidth=1.0)
    ax.set_aspect("equal")
    ax.autoscale_view()
    ax.set_title(f"frame {frame.record.frame}, P/E = {rounding.significant(frame.record.pressure_applied / young)}")
    return mappable


def force_chains_png(frame: Frame, path: str | Path, threshold: float = 1e-9, young: float = 1.0) -> Path:
    """PNG of :func:`draw_frame` with the force network drawn."""
    figure, axes = new_figure(size=(7.0, 6.0))
    draw_frame(axes[0, 0], frame, young, forces=True, threshold=threshold)
    return save_figure(figure, path)


def phi_Z_vs_P_png(rows: Sequence[Mapping[str, float]], path: str | Path) -> Path:
    """PNG of phi and of Z, Z_no_rattlers, Z_bulk against the contact pressure P, one point per
    row of the measures table (filled: equilibrated frames); log P axis when all P > 0."""
    column = {name: np.array([row[name] for row in rows], dtype=float)
              for name in ("P", "phi", "Z", "Z_no_rattlers", "Z_bulk", "equilibrated")}
    P, equilibrated = column["P"], column["equilibrated"] > 0
    figure, axes = new_figure(1, 2)
    for ax, names in zip(axes[0], (("phi",), ("Z", "Z_no_rattlers", "Z_bulk"))):
        for name in names:
            line, = ax.plot(P, column[name], "-", linewidth=0.8, label=name)
            ax.plot(P[equilibrated], column[name][equilibrated], "o", color=line.get_color())
        ax.set_xlabel("P (granular stress)")
        if np.all(P > 0):
            ax.set_xscale("log")
        ax.legend()
    axes[0, 0].set_ylabel(r"$\phi$")
    axes[0, 1].set_ylabel("Z")
    return save_figure(figure, path)


def _fit_curve(fit: FitResult, points: int = 200) -> tuple[np.ndarray, np.ndarray]:
    """phi (points,) spanning the fitted range, and the fitted law there."""
    phi = np.linspace(*fit.phi_range, points)
    return phi, fit.predict(phi)


def plot_compaction(ax, pressure_over_E: np.ndarray, phi: np.ndarray, label: str = "",
                    fits: Sequence[tuple[str, FitResult, str]] = (), color=None) -> None:
    """Fig. 2: phi against P/E (markers) with fitted laws P(phi) (name, fit, line style; an empty
    name draws the line without a legend entry), in ``color``."""
    ax.plot(pressure_over_E, phi, "o", color=color, label=label or None)
    for name, fit, style in fits:
        fit_phi, fit_pressure = _fit_curve(fit)
        ok = fit_pressure > 0
        ax.plot(fit_pressure[ok], fit_phi[ok], style, color=color, linewidth=1, label=name or None)
    ax.set_xlabel("P/E")
    ax.set_ylabel(r"$\phi$")


def plot_bulk_modulus(ax, phi: np.ndarray, K_over_E: np.ndarray, label: str = "",
                      predictions: Sequence[tuple[str, np.ndarray, np.ndarray, str]] = (), color=None) -> None:
    """Fig. 3: K/E against phi (markers, the finite positive K only) with predictions (name, phi,
    K/E, line style) as lines, e.g. Eq. 3 and the modulus of the Platzer fit; log K axis."""
    finite = np.isfinite(K_over_E) & (K_over_E > 0)
    ax.plot(phi[finite], K_over_E[finite], "o", color=color, label=label or None)
    for name, x, y, style in predictions:
        ax.plot(x, y, style, color=color, linewidth=1, label=name or None)
    ax.set_yscale("log")
    ax.set_xlabel(r"$\phi$")
    ax.set_ylabel("K/E")


def plot_coordination(ax, dphi: np.ndarray, dZ: np.ndarray, label: str = "", marker: str = "o", color=None,
                      laws: Sequence[tuple[str, float, float, str, str]] = (),
                      span: tuple[float, float] | None = None) -> None:
    """Fig. 4: Z - Z0 against phi - phi0 (n,) in log-log axes (the points with both > 0), with
    power laws Z - Z0 = xi (phi - phi0)^alpha (name, xi, alpha, line style, colour) over ``span``
    (default: the points' range)."""
    ok = (dphi > 0) & (dZ > 0)
    ax.loglog(dphi[ok], dZ[ok], marker, color=color, label=label or None)
    if laws:
        x = np.geomspace(*(span or (dphi[ok].min(), dphi[ok].max())), 100)
        for name, xi, alpha, style, line_colour in laws:
            ax.loglog(x, xi * x**alpha, style, color=line_colour, label=name or None)
    ax.set_xlabel(r"$\phi - \phi_0$")
    ax.set_ylabel(r"$Z - Z_0$")


def plot_single_particle(ax, curves: Mapping[str, tuple[np.ndarray, np.ndarray]], fit: FitResult | None = None) -> None:
    """Fig. 5: phi_p against P_p/E for several meshes, curves {label: (P_p/E, phi_p)}, with the
    Eq. 2 fit."""
    for name, (pressure_over_E, phi_p) in curves.items():
        ax.plot(pressure_over_E, phi_p, "o-", markersize=3, label=name)
    if fit is not None:
        fit_phi, fit_pressure = _fit_curve(fit)
        ax.plot(fit_pressure, fit_phi, "--", color="0.5",
                label=rf"Eq. 2: b = {rounding.with_error(fit.params['b'], fit.stderr.get('b'))}, "
                      rf"$\phi_{{p,max}}$ = {rounding.with_error(fit.params['phi_p_max'], fit.stderr.get('phi_p_max'))}")
    ax.set_xlabel(r"$P_p/E$")
    ax.set_ylabel(r"$\phi_p$")
    ax.legend()


# --- the paper's figures of a compaction study (post.compaction) -------------------------------


def figure_views(frames: Sequence[Frame], title: str, young: float = 1.0, forces: bool = False):
    """Fig. 1: the frames side by side, rigid disks grey, soft disks coloured by their pressure
    p/E (a colorbar per view), the force network over them if ``forces`` (:func:`draw_frame`)."""
    fig, axes = new_figure(1, len(frames), size=(4.5, 4.2))
    for ax, frame in zip(axes[0], frames):
        draw_frame(ax, frame, young, forces)
        ax.set_title(f"P/E = {rounding.significant(frame.record.pressure_applied / young)}")
    fig.suptitle(title)
    return fig


def _by_mu(result: Compaction):
    groups = result.groups
    mus, kappas = sorted({mu for _, mu in groups}), sorted({k for k, _ in groups})
    return groups, mus, kappas, {k: f"C{i}" for i, k in enumerate(kappas)}


def _panels_per_mu(result: Compaction, title: str, key: str, draw) -> object:
    """A figure with one panel per μ; ``draw(ax, group, label, colour)`` draws each (κ, μ) group
    in its panel, a colour per κ; ``key`` explains the lines."""
    groups, mus, kappas, colour = _by_mu(result)
    fig, axes = new_figure(1, max(1, len(mus)), size=(5.5, 4.5))
    for ax, mu in zip(axes[0], mus):
        for kappa in kappas:
            if (kappa, mu) in groups:
                draw(ax, groups[(kappa, mu)], rf"$\kappa$ = {kappa:g}", colour[kappa])
        ax.set_title(rf"{title}, $\mu$ = {mu:g}")
        ax.legend(fontsize=8)
        ax.text(0.02, 0.98, key, transform=ax.transAxes, va="top", fontsize=7)
    return fig


def figure_compaction(result: Compaction):
    """Fig. 2: φ(P/E) per μ, a colour per κ, with Eq. 5 (solid) and Platzer (dotted)."""
    def draw(ax, g, label, colour):
        laws = [("", f, style) for f, style in ((g.eq5, "-"), (g.platzer, ":")) if f is not None]
        plot_compaction(ax, g.P, g.phi, label, laws, colour)
        ax.set_xscale("log")

    return _panels_per_mu(result, "Fig. 2", "markers: simulation\nsolid: Eq. 5 (fitted $\\phi_{max}$)\n"
                          "dotted: Platzer et al.", draw)


def figure_bulk_modulus(result: Compaction):
    """Fig. 3: K/E(φ) per μ, a colour per κ, with Eq. 3 (solid) and the Platzer modulus (dotted)."""
    from post import models

    def draw(ax, g, label, colour):
        finite = np.isfinite(g.K) & (g.K > 0)
        lines = []
        if finite.any():
            order = np.argsort(g.phi[finite])
            lines.append(("", g.phi[finite][order], g.eq3[finite][order], "-"))
            if g.platzer is not None:
                x = np.linspace(g.phi.min(), g.phi.max(), 100)
                lines.append(("", x, models.log_compaction_modulus(x, g.platzer.params["P0"],
                                                                   g.platzer.params["phi_max"]), ":"))
        plot_bulk_modulus(ax, g.phi, g.K, label, lines, colour)

    return _panels_per_mu(result, "Fig. 3", "markers: K = $\\phi$ dP/d$\\phi$\nsolid: Eq. 3, "
                          "Z$\\phi$K$_p$/2$\\pi$ ($\\phi_{max}(\\kappa)$ of Eq. 5)\ndotted: Platzer modulus", draw)


def figure_coordination(result: Compaction, reference: tuple[float, float] | None = None):
    """Fig. 4: Z − Z₀ against φ − φ₀ for every (κ, μ), with the law fitted over all runs and a
    ``reference`` (ξ, α), e.g. the paper's."""
    groups, mus, kappas, colour = _by_mu(result)
    fig, axes = new_figure(size=(5.5, 4.5))
    ax = axes[0, 0]
    markers = {mu: m for mu, m in zip(mus, "os^v")}
    for (kappa, mu) in groups:
        sel = [p for p in result.points if p["kappa"] == kappa and p["mu"] == mu]
        plot_coordination(ax, np.array([p["phi"] - p["phi0"] for p in sel]), np.array([p["Z"] - p["Z0"] for p in sel]),
                          rf"$\kappa$ = {kappa:g}, $\mu$ = {mu:g}", markers.get(mu, "o"), colour[kappa])
    glob = result.coordination_all
    if glob is not None:
        laws = [(rf"fit: $\xi$ = {rounding.with_error(glob.params['xi'], glob.stderr.get('xi'))}, "
                 rf"$\alpha$ = {rounding.with_error(glob.params['alpha'], glob.stderr.get('alpha'))}",
                 glob.params["xi"], glob.params["alpha"], "--", "k")]
        if reference is not None:
            laws.append((rf"paper: $\xi$ = {reference[0]}, $\alpha$ = {reference[1]}", *reference, ":", "0.5"))
        plot_coordination(ax, np.zeros(0), np.zeros(0), laws=laws,
                          span=(max(glob.phi_range[0] - 1.0, 1e-4), glob.phi_range[1] - 1.0))
    ax.set_ylabel(rf"{result.z_column} $- Z_0$")
    ax.set_title("Fig. 4")
    ax.legend(fontsize=7)
    return fig


def figure_single_particle_law(result: Compaction):
    """Fig. 5: the single-particle law used (Eq. 2), and φ_max(κ) of Eq. 5 and Platzer per μ."""
    from post import models

    groups, mus, kappas, _ = _by_mu(result)
    law = result.law
    fig, axes = new_figure(1, 2, size=(5.0, 4.2))
    phi_p = np.linspace(np.pi / 4, law.phi_p_max - 1e-3, 200)
    ax = axes[0, 0]
    ax.plot(models.single_particle_pressure(phi_p, law.b, law.phi_p_max), phi_p, "--", color="0.4",
            label=rf"Eq. 2: b = {law.b:.3g}, $\phi_{{p,max}}$ = {law.phi_p_max:.3g}")
    ax.set_xscale("log")
    ax.set_xlabel(r"$P_p/E$")
    ax.set_ylabel(r"$\phi_p$")
    ax.set_title("Fig. 5 (law used)" + (" - PAPER'S b" if law.paper_default else ""))
    ax.legend(fontsize=7)
    ax = axes[0, 1]
    for mu in mus:
        for name, key, style in (("Eq. 5", "eq5", "o-"), ("Platzer", "platzer", "s:")):
            ks = [k for k in kappas if groups.get((k, mu)) and getattr(groups[(k, mu)], key) is not None]
            ax.plot(ks, [getattr(groups[(k, mu)], key).params["phi_max"] for k in ks], style,
                    label=rf"{name}, $\mu$ = {mu:g}")
    ax.set_xlabel(r"$\kappa$")
    ax.set_ylabel(r"$\phi_{max}$")
    ax.set_title(r"fitted $\phi_{max}(\kappa)$")
    ax.legend(fontsize=7)
    return fig
