"""Single-particle study, stage 3: measures, the fit of Eq. 2 and a figure like the paper's Fig. 5.

Reads the VTK frames of WORKDIR/out through ``post`` and writes WORKDIR/out/post/:

- measures.csv: one row per frame (columns of post.table: pressure_applied, phi = phi_p, the
  current disk area over the box area, P_walls the mean wall pressure, ...), reduced units
  (E = 1, R = 1: the scene's Young modulus divides the pressures of the fit and the figure);
- fit.json: Eq. 2, P_p/E = -b ln[(phi_p,max - phi_p)/(phi_p,max - pi/4)], fitted (b and
  phi_p,max free, phi_p,0 = pi/4) on the equilibrated frames with P_walls/E <= --fit-p-max
  and phi_p <= --fit-phi-max; the fitted phi range is stored and printed;
- single_particle.png: phi_p against P_p/E (P_walls/E), with the fit (paper Fig. 5).

Extra --compare DIR options add other runs (other meshes) to the figure.
"""

from __future__ import annotations

if not __package__:  # run as a file (python studies/X/stage.py): studies/entry.py
    import pathlib, sys; sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2]))
    from studies.entry import run_as_file; run_as_file(__file__)

import argparse
import json
import sys
from pathlib import Path

import numpy as np


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--workdir", required=True, help="study folder (reads WORKDIR/out)")
    ap.add_argument("--fit-p-max", type=float, default=np.inf, help="largest P/E in the fit (default all)")
    ap.add_argument("--fit-phi-max", type=float, default=0.99,
                    help="largest phi_p in the fit (default 0.99: coarse meshes fill the box, phi_p -> 1)")
    ap.add_argument("--compare", action="append", default=[], metavar="DIR",
                    help="another study folder to draw in the figure (repeatable)")
    a = ap.parse_args(argv)
    from post import rounding
    from post.errors import OutputError
    from post.single_particle import curve, fit, mesh_label
    from post.table import write_measures

    out = Path(a.workdir) / "out"
    try:
        rows, p, phi = curve(out)
        label = mesh_label(out)
        compared = {mesh_label(Path(other) / "out"): curve(Path(other) / "out")[1:] for other in a.compare}
    except OutputError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    target = out / "post"
    write_measures(rows, target / "measures.csv")
    try:
        result, n = fit(p, phi, a.fit_p_max, a.fit_phi_max)
    except ValueError as exc:
        ap.error(str(exc))
    info = {"b": result.params["b"], "phi_p_max": result.params["phi_p_max"],
            "stderr": result.stderr, "phi_range": result.phi_range, "n_points": n,
            "rms_relative": result.rms_relative, "phi_p0": float(np.pi / 4),
            "fit_p_max": a.fit_p_max if np.isfinite(a.fit_p_max) else None, "fit_phi_max": a.fit_phi_max}
    (target / "fit.json").write_text(json.dumps(info, indent=2) + "\n")

    from post.plots import new_figure, plot_single_particle, save_figure

    curves = {label: (p, phi), **compared}
    fig, axes = new_figure(size=(5.5, 4.2))
    ax = axes[0, 0]
    plot_single_particle(ax, curves, result)
    ax.set_xscale("log")
    ax.set_title(f"single particle, Eq. 2 fitted on phi_p in [{result.phi_range[0]:.3f}, {result.phi_range[1]:.3f}]",
                 fontsize=8)
    save_figure(fig, target / "single_particle.png")
    print(f"{target / 'measures.csv'}\nEq. 2: b = {rounding.with_error(info['b'], result.stderr['b'])}, phi_p,max = "
          f"{rounding.with_error(info['phi_p_max'], result.stderr['phi_p_max'])} (fitted on {n} stages, phi_p in "
          f"[{rounding.phi(result.phi_range[0])}, {rounding.phi(result.phi_range[1])}], "
          f"rms {rounding.significant(100 * result.rms_relative, 2)} %)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
