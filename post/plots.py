"""Figures with matplotlib (Agg, no pyplot state): force chains of a frame, phi and Z against P,
and helpers that draw the paper's Figs. 2-5 on a given Axes so that the studies compose them.

matplotlib is imported inside the functions (about 0.5 s), never at package import.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from post import measures

if TYPE_CHECKING:
    from post.fits import FitResult
    from post.frames import Frame

_T6_OUTLINE = [0, 3, 1, 4, 2, 5]  # T6 nodes around the element: corner, mid-side, corner, ...


def new_figure(nrows: int = 1, ncols: int = 1, size: tuple[float, float] = (5.0, 4.0)):
    """A figure (Agg canvas) and its (nrows, ncols) array of Axes."""
    from matplotlib.figure import Figure

    figure = Figure(figsize=(size[0] * ncols, size[1] * nrows), layout="constrained")
    return figure, figure.subplots(nrows, ncols, squeeze=False)


def save_figure(figure, path: str | Path, dpi: int = 150) -> Path:
    """Save figure as path (format from the suffix), creating the folder."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path, dpi=dpi)
    return path


def draw_force_chains(ax, frame: Frame, threshold: float = 1e-9, max_width: float = 3.0) -> None:
    """Draw a frame: rigid disks grey, deformable meshes coloured by their cell pressure, the box,
    and the active contacts as segments between centres of width proportional to fn."""
    from matplotlib.cm import ScalarMappable
    from matplotlib.collections import LineCollection, PatchCollection, PolyCollection
    from matplotlib.colors import Normalize
    from matplotlib.patches import Circle

    bodies, contacts = frame.bodies, frame.contacts
    radii = bodies.radius[bodies.rigid_ids]
    ax.add_collection(PatchCollection([Circle(c, r) for c, r in zip(bodies.rigid_centres, radii)],
                                      facecolor="0.75", edgecolor="0.4", linewidth=0.3))
    if bodies.meshes:
        pressure = np.concatenate([m.pressure for m in bodies.meshes])
        norm = Normalize(pressure.min(), max(pressure.max(), pressure.min() + 1e-300))
        for m in bodies.meshes:
            outline = m.cells[:, _T6_OUTLINE] if m.element == "T6" else m.cells
            ax.add_collection(PolyCollection(bodies.points[outline], array=m.pressure, cmap="viridis", norm=norm,
                                             edgecolor="0.3", linewidth=0.1))
        ax.figure.colorbar(ScalarMappable(norm, "viridis"), ax=ax, label="cell pressure")
    active = measures.active_contacts(contacts.fn, threshold)
    if active.any():
        fn = contacts.fn[active]
        ax.add_collection(LineCollection(contacts.segments[active], linewidths=max_width * fn / fn.max(),
                                         colors="firebrick"))
    left, right, bottom, top = frame.walls.position
    ax.plot([left, right, right, left, left], [bottom, bottom, top, top, bottom], color="k", linewidth=1.0)
    ax.set_aspect("equal")
    ax.autoscale_view()
    ax.set_title(f"frame {frame.record.frame}, P applied = {frame.record.pressure_applied:.3g}")


def force_chains_png(frame: Frame, path: str | Path, threshold: float = 1e-9) -> Path:
    """PNG of :func:`draw_force_chains`."""
    figure, axes = new_figure(size=(7.0, 6.0))
    draw_force_chains(axes[0, 0], frame, threshold)
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
                    fits: Sequence[tuple[str, FitResult]] = (), **style) -> None:
    """Fig. 2: phi against P/E (markers) with fitted laws (lines, e.g. Platzer and Eq. 5)."""
    ax.plot(pressure_over_E, phi, "o", label=label, **style)
    for name, fit in fits:
        fit_phi, fit_pressure = _fit_curve(fit)
        ax.plot(fit_pressure, fit_phi, "--", label=name)
    ax.set_xlabel("P/E")
    ax.set_ylabel(r"$\phi$")
    ax.legend()


def plot_bulk_modulus(ax, phi: np.ndarray, K_over_E: np.ndarray, label: str = "",
                      predictions: Sequence[tuple[str, np.ndarray, np.ndarray]] = (), **style) -> None:
    """Fig. 3: K/E against phi (markers) with predictions (name, phi, K/E) as lines, e.g. Eq. 3 and
    the modulus of the Platzer fit; log K axis."""
    ax.plot(phi, K_over_E, "o", label=label, **style)
    for name, x, y in predictions:
        ax.plot(x, y, "--", label=name)
    ax.set_yscale("log")
    ax.set_xlabel(r"$\phi$")
    ax.set_ylabel("K/E")
    ax.legend()


def plot_coordination(ax, phi: np.ndarray, Z: np.ndarray, phi0: float, Z0: float, label: str = "",
                      fit: FitResult | None = None, **style) -> None:
    """Fig. 4: Z - Z0 against phi - phi0 in log-log axes (points with both > 0), with the power
    law Z - Z0 = xi (phi - phi0)^alpha of a fit."""
    above = (phi > phi0) & (Z > Z0)
    ax.loglog(phi[above] - phi0, Z[above] - Z0, "o", label=label, **style)
    if fit is not None:
        fit_phi, fit_Z = _fit_curve(fit)
        ax.loglog(fit_phi - phi0, fit_Z - Z0, "--",
                  label=rf"$\xi$ = {fit.params['xi']:.3g}, $\alpha$ = {fit.params['alpha']:.3g}")
    ax.set_xlabel(r"$\phi - \phi_0$")
    ax.set_ylabel(r"$Z - Z_0$")
    ax.legend()


def plot_single_particle(ax, curves: Mapping[str, tuple[np.ndarray, np.ndarray]], fit: FitResult | None = None) -> None:
    """Fig. 5: phi_p against P_p/E for several meshes, curves {label: (P_p/E, phi_p)}, with the
    Eq. 2 fit."""
    for name, (pressure_over_E, phi_p) in curves.items():
        ax.plot(pressure_over_E, phi_p, "o-", markersize=3, label=name)
    if fit is not None:
        fit_phi, fit_pressure = _fit_curve(fit)
        ax.plot(fit_pressure, fit_phi, "--", color="0.5",
                label=rf"Eq. 2: b = {fit.params['b']:.3g}, $\phi_{{p,max}}$ = {fit.params['phi_p_max']:.3g}")
    ax.set_xlabel(r"$P_p/E$")
    ax.set_ylabel(r"$\phi_p$")
    ax.legend()
