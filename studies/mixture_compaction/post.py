"""Stage 3 of the mixture compaction study: measures of every run and the paper's analysis.

Per run: DIR/runs/<name>/out/post/measures.csv (post.table: φ, Z, stress from the contacts, P from
contacts and from walls, K = φ dP/dφ on the equilibrated frames).

Study level, in DIR/post/ (equilibrated frames only; seeds of one (κ, μ) pooled):
- table1.csv: φ₀, Z₀ per (κ, μ) (first equilibrated stage, P/E = p_min), the paper's Table 1;
- fits.csv: every fitted parameter (law, κ, μ, parameter, value, stderr, fitted φ range, RMS);
  Platzer et al. (P₀, φ_max) per (κ, μ); Z − Z₀ = ξ(φ − φ₀)^α per (κ, μ) and over all runs
  ("all"); Eq. 5 (φ_max only; b, ξ, α, Z₀, φ₀ given); the single-particle law used (b, φ_p,max);
- errors.csv: per (κ, μ), the error of Eq. 5 and of the Platzer fit on φ(P/E) (RMS and max of
  |φ_model(P) − φ| and of P_model(φ)/P − 1) and of the Eq. 3 check (K against Zφ K_p / 2π);
- curves.csv: every equilibrated point (κ, μ, seed, stage, P/E, φ, Z, K/E, predictions);
- fig1_views.png … fig5_single_particle.png, phi_max_vs_kappa.png (like the paper's Figs. 1–5);
- summary.md: the toolkit's numbers beside the paper's, run times, and where b came from.

b and φ_p,max (Eq. 2, single particle): --b / --phi-p-max; else --single-particle PATH (a
single-particle study folder, whose out/post/fit.json or out/post/measures.csv is used; a JSON
file with "b" and "phi_p_max"; a CSV table of fits per mesh with columns element, elements, b,
phi_p_max; or a single-particle measures.csv, fitted here with Eq. 2); else the row of
studies/single_particle/results/refinement_fits.csv with the study's element type and the
closest number of elements (the same discretisation as the study's soft disks); else b = 0.14,
THE PAPER'S VALUE, and φ_p,max = 1 (an assumption: an incompressible disk fills its square box),
flagged as such in every output.
"""

import argparse
import csv
import json
import math
import os
import sys
from pathlib import Path

import numpy as np

from compute.dispatch import run_status

REPO = Path(__file__).resolve().parents[2]
SINGLE_PARTICLE_CANDIDATES = ("studies/single_particle/results/refinement_fits.csv",
                              "studies/single_particle/results/fit.json")
PAPER_B = 0.14
ASSUMED_PHI_P_MAX = 1.0
# Cárdenas-Barrantes et al. 2021, Table 1 (N = 1500), and the fits of Sec. 3
PAPER_PHI0 = {0.0: {0.2: 0.815, 0.5: 0.811, 0.8: 0.807, 1.0: 0.807},
              0.2: {0.2: 0.814, 0.5: 0.811, 0.8: 0.807, 1.0: 0.805}}
PAPER_Z0 = {0.0: {0.2: 3.4, 0.5: 3.6, 0.8: 3.5, 1.0: 3.4}, 0.2: {0.2: 3.3, 0.5: 3.7, 0.8: 3.5, 1.0: 3.5}}
PAPER_XI, PAPER_ALPHA = 5.1, 0.5
Z_COLUMNS = ("Z", "Z_no_rattlers", "Z_bulk", "Z_constraints")


# ------------------------------------------------------------------------------ inputs


def _law_from_file(path: Path, element: str, elements: int) -> dict:
    """b and phi_p_max from a single-particle result file (module docstring)."""
    if path.suffix == ".json":
        data = json.loads(path.read_text())
        if not all(isinstance(data.get(k), (int, float)) for k in ("b", "phi_p_max")):
            raise SystemExit(f"{path}: expected numbers 'b' and 'phi_p_max'")
        rng = data.get("phi_range")
        where = f" (phi_p in [{rng[0]:.4f}, {rng[1]:.4f}])" if isinstance(rng, list) and len(rng) == 2 else ""
        return {"b": float(data["b"]), "phi_p_max": float(data["phi_p_max"]), "source": f"{path}{where}"}
    with path.open(newline="") as stream:
        rows = list(csv.DictReader(stream))
    if rows and {"b", "phi_p_max", "element", "elements"} <= set(rows[0]):  # a table of fits per mesh
        uniform = [r for r in rows if not r.get("boundary_segments")] or rows  # the study's meshes are uniform
        same = [r for r in uniform if r["element"] == element] or uniform
        row = min(same, key=lambda r: abs(int(r["elements"]) - elements))
        return {"b": float(row["b"]), "phi_p_max": float(row["phi_p_max"]),
                "source": f"{path}, row {row['element']} x {row['elements']} elements "
                          f"(phi_p in [{float(row['phi_min']):.4f}, {float(row['phi_max']):.4f}])"}
    from post.fits import fit_single_particle
    from post.table import read_measures

    m = read_measures(path)
    keep = m["equilibrated"].astype(bool) if "equilibrated" in m.dtype.names else np.ones(len(m), bool)
    pressure = m["P_walls"] if "P_walls" in m.dtype.names else m["pressure_applied"]
    fit = fit_single_particle(m["phi"][keep], pressure[keep])
    return {"b": fit.params["b"], "phi_p_max": fit.params["phi_p_max"],
            "source": f"Eq. 2 fitted to {path} (phi_p in [{fit.phi_range[0]:.4f}, {fit.phi_range[1]:.4f}])"}


def single_particle_law(args, study: dict) -> dict:
    """{"b", "phi_p_max", "source", "paper_default": bool} (module docstring for the order)."""
    if args.b is not None:
        return {"b": args.b, "phi_p_max": args.phi_p_max or ASSUMED_PHI_P_MAX, "paper_default": False,
                "source": "command line (--b)" + ("" if args.phi_p_max else f", phi_p_max assumed {ASSUMED_PHI_P_MAX}")}
    if args.single_particle:
        path = Path(args.single_particle)
        if path.is_dir():
            path = next((p for p in (path / "out" / "post" / "fit.json", path / "out" / "post" / "measures.csv")
                         if p.is_file()), path / "out" / "post" / "fit.json")
        if not path.is_file():
            raise SystemExit(f"--single-particle {args.single_particle}: no fit.json or measures.csv at {path}")
        paths = [path]
    else:
        paths = [p for p in (REPO / c for c in SINGLE_PARTICLE_CANDIDATES) if p.is_file()]
    for path in paths:
        law = {**_law_from_file(path, study.get("element", "T3"), int(study.get("elements", 92))), "paper_default": False}
        if args.phi_p_max:
            law["phi_p_max"] = args.phi_p_max
        return law
    return {"b": PAPER_B, "phi_p_max": args.phi_p_max or ASSUMED_PHI_P_MAX, "paper_default": True,
            "source": f"PAPER'S VALUE b = {PAPER_B} (no single-particle result found), phi_p_max "
                      + (f"{args.phi_p_max} (--phi-p-max)" if args.phi_p_max else f"= {ASSUMED_PHI_P_MAX} assumed")}


def measure_runs(w: Path, study: dict, threshold: float) -> dict:
    """Write every run's out/post/measures.csv; return {name: rows} for the runs with frames."""
    from post import measures
    from post.errors import OutputError
    from post.table import measure_output, write_measures

    tables = {}
    for run in study["runs"]:
        out = w / run["out"]
        if not (out / "frames.csv").is_file():
            print(f"  {run['name']}: no output yet, left out", flush=True)
            continue
        try:
            rows = measure_output(out, measures.default_min_contacts(run["mu"]), threshold)
        except OutputError as exc:
            print(f"  {run['name']}: unreadable output, left out ({exc})", flush=True)
            continue
        write_measures(rows, out / "post" / "measures.csv")
        status = run_status(out)
        print(f"  {run['name']}: {len(rows)} frames ({status})", flush=True)
        tables[run["name"]] = rows
    return tables


# ------------------------------------------------------------------------------ analysis


def _phi_of_pressure(model, pressure: np.ndarray, phi0: float, phi_max: float) -> np.ndarray:
    """Invert a law P(φ) increasing on (φ₀, φ_max) from 0 to ∞: φ (n,) at the pressures (n,)."""
    from scipy.optimize import brentq

    out = np.full(len(pressure), np.nan)
    hi = phi_max - 1e-12 * max(1.0, phi_max)
    for k, p in enumerate(pressure):
        try:
            out[k] = brentq(lambda x: model(np.array([x]))[0] - p, phi0, hi, xtol=1e-14)
        except ValueError:
            pass
    return out


def _errors(model, phi: np.ndarray, pressure: np.ndarray, phi0: float, phi_max: float) -> dict:
    """Errors of a fitted law on the points: in φ at given P (|φ_model(P) − φ|), and in P at given φ
    (P_model(φ)/P − 1, over the points above φ₀)."""
    dphi = _phi_of_pressure(model, pressure, phi0, phi_max) - phi
    above = phi > phi0 + 1e-12  # the law gives P = 0 at phi0 itself: no relative error there
    rel = model(phi[above]) / pressure[above] - 1 if above.any() else np.array([np.nan])
    return {"phi_rms": float(np.sqrt(np.nanmean(dphi**2))), "phi_max_abs": float(np.nanmax(np.abs(dphi))),
            "P_rms_rel": float(np.sqrt(np.mean(rel**2))), "P_max_rel": float(np.max(np.abs(rel)))}


def analyse(study: dict, tables: dict, law: dict, z_column: str, xi_alpha: str) -> dict:
    """Everything of the study level from the per-run tables (see the module docstring)."""
    from post import fits, models

    young = float(study.get("young", 1.0))
    by_name = {r["name"]: r for r in study["runs"]}
    points = []  # one dict per equilibrated frame
    for name, rows in tables.items():
        run = by_name[name]
        eq = [r for r in rows if r["equilibrated"]]
        if not eq:
            continue
        for r in eq:
            points.append({"name": name, "kappa": run["kappa"], "mu": run["mu"], "seed": run["seed"],
                           "stage": int(r["stage"]), "P_over_E": r["P"] / young, "P_walls_over_E": r["P_walls"] / young,
                           "pressure_applied": r["pressure_applied"], "phi": r["phi"], "Z": r[z_column],
                           "K_over_E": r["K"] / young, "phi0": eq[0]["phi"], "Z0": eq[0][z_column]})
    groups = sorted({(p["kappa"], p["mu"]) for p in points})
    result = {"law": law, "z_column": z_column, "groups": {}, "points": points, "fit_rows": [], "notes": []}

    def add_fit(law_name, kappa, mu, fit, names, shift=0.0):
        """One fits.csv row per parameter; the fitted range is phi (minus ``shift``: the
        coordination fits run on 1 + phi - phi0, reported as phi - phi0)."""
        for n in names:
            result["fit_rows"].append({"law": law_name, "kappa": kappa, "mu": mu, "parameter": n,
                                       "value": fit.params.get(n, fit.fixed.get(n)) if fit else np.nan,
                                       "stderr": fit.stderr.get(n, 0.0) if fit else np.nan,
                                       "phi_min": fit.phi_range[0] - shift if fit else np.nan,
                                       "phi_max_fitted": fit.phi_range[1] - shift if fit else np.nan,
                                       "rms": fit.rms if fit else np.nan,
                                       "rms_relative": fit.rms_relative if fit else np.nan})

    def attempt(what, f):
        try:
            return f()
        except (ValueError, RuntimeError, TypeError) as exc:
            result["notes"].append(f"{what}: not fitted ({exc})")
            return None

    # Z - Z0 = xi (phi - phi0)^alpha over all runs (each with its own phi0, Z0): shift to phi0 = 1, Z0 = 0
    dphi = np.array([p["phi"] - p["phi0"] for p in points])
    dZ = np.array([p["Z"] - p["Z0"] for p in points])
    glob = attempt("coordination law over all runs", lambda: fits.fit_coordination(1.0 + dphi, dZ, 1.0, 0.0))
    result["coordination_all"] = glob
    add_fit("coordination", "all", "all", glob, ("xi", "alpha"), shift=1.0)

    for kappa, mu in groups:
        sel = [p for p in points if p["kappa"] == kappa and p["mu"] == mu]
        phi = np.array([p["phi"] for p in sel])
        P = np.array([p["P_over_E"] for p in sel])
        Z = np.array([p["Z"] for p in sel])
        K = np.array([p["K_over_E"] for p in sel])
        seeds = sorted({p["seed"] for p in sel})
        phi0s = np.array([next(p["phi0"] for p in sel if p["seed"] == s) for s in seeds])
        Z0s = np.array([next(p["Z0"] for p in sel if p["seed"] == s) for s in seeds])
        phi0, Z0 = float(phi0s.mean()), float(Z0s.mean())
        g = {"kappa": kappa, "mu": mu, "seeds": seeds, "n_points": len(sel), "phi0": phi0, "Z0": Z0,
             "phi0_std": float(phi0s.std(ddof=1)) if len(seeds) > 1 else np.nan,
             "Z0_std": float(Z0s.std(ddof=1)) if len(seeds) > 1 else np.nan,
             "phi": phi, "P": P, "Z": Z, "K": K}
        g["platzer"] = attempt(f"Platzer (kappa {kappa:g}, mu {mu:g})", lambda: fits.fit_platzer(phi, P, phi0))
        add_fit("platzer", kappa, mu, g["platzer"], ("P0", "phi_max"))
        d_phi = np.array([p["phi"] - p["phi0"] for p in sel])
        d_Z = np.array([p["Z"] - p["Z0"] for p in sel])
        g["coordination"] = attempt(f"coordination (kappa {kappa:g}, mu {mu:g})",
                                    lambda: fits.fit_coordination(1.0 + d_phi, d_Z, 1.0, 0.0))
        add_fit("coordination", kappa, mu, g["coordination"], ("xi", "alpha"), shift=1.0)
        source = g["coordination"] if xi_alpha == "group" else glob
        xi, alpha = (source.params["xi"], source.params["alpha"]) if source else (PAPER_XI, PAPER_ALPHA)
        if source is None:
            result["notes"].append(f"Eq. 5 (kappa {kappa:g}, mu {mu:g}): xi, alpha = the paper's {PAPER_XI}, {PAPER_ALPHA}")
        g["xi_alpha"] = (xi, alpha)
        g["eq5"] = attempt(f"Eq. 5 (kappa {kappa:g}, mu {mu:g})",
                           lambda: fits.fit_eq5(phi, P, law["b"], xi, alpha, Z0, phi0))
        add_fit("eq5", kappa, mu, g["eq5"], ("phi_max",))
        # scatter between seeds: phi_max of Eq. 5 and Platzer fitted to each seed alone
        for key in ("eq5", "platzer"):
            values = []
            for seed in seeds if len(seeds) > 1 else []:
                mine = [p for p in sel if p["seed"] == seed]
                x, y = np.array([p["phi"] for p in mine]), np.array([p["P_over_E"] for p in mine])
                f0, z0 = mine[0]["phi0"], mine[0]["Z0"]
                fit = attempt(f"{key} (kappa {kappa:g}, mu {mu:g}, seed {seed})",
                              lambda: fits.fit_eq5(x, y, law["b"], xi, alpha, z0, f0) if key == "eq5"
                              else fits.fit_platzer(x, y, f0))
                if fit is not None:
                    values.append(fit.params["phi_max"])
            g[f"{key}_phi_max_seed_std"] = float(np.std(values, ddof=1)) if len(values) > 1 else np.nan
            result["fit_rows"].append({"law": f"{key} per seed", "kappa": kappa, "mu": mu, "parameter": "phi_max std",
                                       "value": g[f"{key}_phi_max_seed_std"], "stderr": np.nan, "phi_min": np.nan,
                                       "phi_max_fitted": np.nan, "rms": np.nan, "rms_relative": np.nan})
        err = {"kappa": kappa, "mu": mu, "n_points": len(sel)}
        for key, fit in (("eq5", g["eq5"]), ("platzer", g["platzer"])):
            e = _errors(fit.predict, phi, P, phi0, fit.params["phi_max"]) if fit else {}
            for k in ("phi_rms", "phi_max_abs", "P_rms_rel", "P_max_rel"):
                err[f"{key}_{k}"] = e.get(k, np.nan)
        # Eq. 3: K against (Z phi / 2 pi) K_p(phi), K_p = b phi / (phi_max - phi) the modulus of Eq. 2 "at
        # equivalent packing fraction": with phi_max = phi_max(kappa) of the Eq. 5 fit (the mapping that
        # turns Eq. 4 into Eq. 5; "eq3"), and literally with the single particle's phi_p,max ("eq3_single")
        finite = np.isfinite(K) & (K > 0)
        for key, top in (("eq3", g["eq5"].params["phi_max"] if g["eq5"] else np.nan), ("eq3_single", law["phi_p_max"])):
            g[key] = np.full(len(K), np.nan)
            err[f"{key}_rms_rel"] = err[f"{key}_max_rel"] = np.nan
            if finite.any() and np.isfinite(top) and top > phi.max():
                check = fits.eq3_check(phi[finite], K[finite], Z[finite], law["b"], top)
                g[key][finite] = check.prediction
                err[f"{key}_rms_rel"] = check.rms_relative
                err[f"{key}_max_rel"] = float(np.max(np.abs(check.relative_error)))
        g["errors"] = err
        for p, e5, e3, e3s in zip(sel, g["eq5"].predict(phi) if g["eq5"] else np.full(len(sel), np.nan), g["eq3"],
                                  g["eq3_single"]):
            p["eq5_P_over_E"], p["eq3_K_over_E"], p["eq3_single_K_over_E"] = float(e5), float(e3), float(e3s)
            p["platzer_P_over_E"] = float(g["platzer"].predict(np.array([p["phi"]]))[0]) if g["platzer"] else np.nan
        result["groups"][(kappa, mu)] = g
    result["fit_rows"].append({"law": "single_particle (Eq. 2)", "kappa": "all", "mu": "all", "parameter": "b",
                               "value": law["b"], "stderr": np.nan, "phi_min": np.nan, "phi_max_fitted": np.nan,
                               "rms": np.nan, "rms_relative": np.nan})
    result["fit_rows"].append({"law": "single_particle (Eq. 2)", "kappa": "all", "mu": "all",
                               "parameter": "phi_p_max", "value": law["phi_p_max"], "stderr": np.nan,
                               "phi_min": np.nan, "phi_max_fitted": np.nan, "rms": np.nan, "rms_relative": np.nan})
    return result


# ------------------------------------------------------------------------------ outputs


def write_csv(path: Path, rows: list[dict], columns: list[str] | None = None) -> Path:
    if columns is None:
        columns = list(rows[0]) if rows else []
    with path.open("w", newline="") as stream:
        writer = csv.DictWriter(stream, fieldnames=columns, extrasaction="ignore")
        writer.writeheader()
        for row in rows:
            writer.writerow({k: (repr(float(v)) if isinstance(v, (float, np.floating)) else v) for k, v in row.items()})
    return path


def figures(w: Path, study: dict, result: dict, target: Path) -> list[Path]:
    from post import models, plots
    from post.frames import read_frame, read_frames_table

    written = []
    groups = result["groups"]
    mus = sorted({mu for _, mu in groups})
    kappas = sorted({k for k, _ in groups})
    colour = {k: f"C{i}" for i, k in enumerate(kappas)}

    # Fig. 1: views of kappa = 0.5 (or the closest), the largest mu, at up to four equilibrated stages
    if groups:
        k1 = min(kappas, key=lambda k: abs(k - 0.5))
        m1 = max(mus)
        run = next((r for r in study["runs"] if r["kappa"] == k1 and r["mu"] == m1 and (w / r["out"] / "frames.csv").is_file()), None)
        if run is not None:
            out = w / run["out"]
            records = [r for r in read_frames_table(out) if r.equilibrated]
            pick = [records[i] for i in sorted({round(x) for x in np.linspace(0, len(records) - 1, min(4, len(records)))})]
            fig, axes = plots.new_figure(1, len(pick), size=(4.5, 4.2))
            for ax, rec in zip(axes[0], pick):
                plots.draw_force_chains(ax, read_frame(out, rec))
                ax.set_title(f"P/E = {rec.pressure_applied:.3g}")
            fig.suptitle(f"kappa = {k1:g}, mu = {m1:g} (grey: rigid; colour: cell pressure)")
            written.append(plots.save_figure(fig, target / "fig1_views.png"))

    # Fig. 2: phi(P/E) with Eq. 5 and Platzer; Fig. 3: K/E(phi) with Eq. 3 and the Platzer modulus
    fig2, ax2 = plots.new_figure(1, max(1, len(mus)), size=(5.5, 4.5))
    fig3, ax3 = plots.new_figure(1, max(1, len(mus)), size=(5.5, 4.5))
    for j, mu in enumerate(mus):
        for kappa in kappas:
            g = groups.get((kappa, mu))
            if g is None:
                continue
            c = colour[kappa]
            ax = ax2[0, j]
            ax.plot(g["P"], g["phi"], "o", color=c, label=rf"$\kappa$ = {kappa:g}")
            for fit, style in ((g["eq5"], "-"), (g["platzer"], ":")):
                if fit is not None:
                    x = np.linspace(fit.phi_range[0], fit.phi_range[1], 200)
                    y = fit.predict(x)
                    ok = y > 0
                    ax.plot(y[ok], x[ok], style, color=c, linewidth=1)
            ax = ax3[0, j]
            finite = np.isfinite(g["K"]) & (g["K"] > 0)
            ax.plot(g["phi"][finite], g["K"][finite], "o", color=c, label=rf"$\kappa$ = {kappa:g}")
            if finite.any():
                order = np.argsort(g["phi"][finite])
                ax.plot(g["phi"][finite][order], g["eq3"][finite][order], "-", color=c, linewidth=1)
                if g["platzer"] is not None:
                    x = np.linspace(g["phi"].min(), g["phi"].max(), 100)
                    ax.plot(x, models.log_compaction_modulus(x, g["platzer"].params["P0"], g["platzer"].params["phi_max"]),
                            ":", color=c, linewidth=1)
        for ax, title in ((ax2[0, j], "Fig. 2"), (ax3[0, j], "Fig. 3")):
            ax.set_title(rf"{title}, $\mu$ = {mu:g}")
            ax.legend(fontsize=8)
        ax2[0, j].set_xscale("log")
        ax2[0, j].set_xlabel("P/E")
        ax2[0, j].set_ylabel(r"$\phi$")
        ax2[0, j].text(0.02, 0.98, "markers: simulation\nsolid: Eq. 5 (fitted $\\phi_{max}$)\ndotted: Platzer et al.",
                       transform=ax2[0, j].transAxes, va="top", fontsize=7)
        ax3[0, j].set_yscale("log")
        ax3[0, j].set_xlabel(r"$\phi$")
        ax3[0, j].set_ylabel("K/E")
        ax3[0, j].text(0.02, 0.98, "markers: K = $\\phi$ dP/d$\\phi$\nsolid: Eq. 3, Z$\\phi$K$_p$/2$\\pi$ ($\\phi_{max}(\\kappa)$ of Eq. 5)\ndotted: Platzer modulus",
                       transform=ax3[0, j].transAxes, va="top", fontsize=7)
    written.append(plots.save_figure(fig2, target / "fig2_compaction.png"))
    written.append(plots.save_figure(fig3, target / "fig3_bulk_modulus.png"))

    # Fig. 4: Z - Z0 against phi - phi0, every (kappa, mu), and the law fitted over all runs
    fig4, ax4 = plots.new_figure(size=(5.5, 4.5))
    ax = ax4[0, 0]
    markers = {mu: m for mu, m in zip(mus, "os^v")}
    for (kappa, mu), g in groups.items():
        sel = [p for p in result["points"] if p["kappa"] == kappa and p["mu"] == mu]
        x = np.array([p["phi"] - p["phi0"] for p in sel])
        y = np.array([p["Z"] - p["Z0"] for p in sel])
        ok = (x > 0) & (y > 0)
        ax.loglog(x[ok], y[ok], markers.get(mu, "o"), color=colour[kappa], label=rf"$\kappa$ = {kappa:g}, $\mu$ = {mu:g}")
    glob = result["coordination_all"]
    if glob is not None:
        x = np.geomspace(max(glob.phi_range[0] - 1.0, 1e-4), glob.phi_range[1] - 1.0, 100)
        ax.loglog(x, glob.params["xi"] * x ** glob.params["alpha"], "k--",
                  label=rf"fit: $\xi$ = {glob.params['xi']:.3g}, $\alpha$ = {glob.params['alpha']:.3g}")
        ax.loglog(x, PAPER_XI * x**PAPER_ALPHA, ":", color="0.5", label=rf"paper: $\xi$ = {PAPER_XI}, $\alpha$ = {PAPER_ALPHA}")
    ax.set_xlabel(r"$\phi - \phi_0$")
    ax.set_ylabel(rf"{result['z_column']} $- Z_0$")
    ax.set_title("Fig. 4")
    ax.legend(fontsize=7)
    written.append(plots.save_figure(fig4, target / "fig4_coordination.png"))

    # Fig. 5: the single-particle law used (Eq. 2), and phi_max against kappa
    law = result["law"]
    fig5, ax5 = plots.new_figure(1, 2, size=(5.0, 4.2))
    phi_p = np.linspace(np.pi / 4, law["phi_p_max"] - 1e-3, 200)
    ax5[0, 0].plot(models.single_particle_pressure(phi_p, law["b"], law["phi_p_max"]), phi_p, "--", color="0.4",
                   label=rf"Eq. 2: b = {law['b']:.3g}, $\phi_{{p,max}}$ = {law['phi_p_max']:.3g}")
    ax5[0, 0].set_xscale("log")
    ax5[0, 0].set_xlabel(r"$P_p/E$")
    ax5[0, 0].set_ylabel(r"$\phi_p$")
    ax5[0, 0].set_title("Fig. 5 (law used)" + (" - PAPER'S b" if law["paper_default"] else ""))
    ax5[0, 0].legend(fontsize=7)
    for mu in mus:
        for name, key, style in (("Eq. 5", "eq5", "o-"), ("Platzer", "platzer", "s:")):
            ks = [k for k in kappas if groups.get((k, mu)) and groups[(k, mu)][key] is not None]
            ax5[0, 1].plot(ks, [groups[(k, mu)][key].params["phi_max"] for k in ks], style,
                           label=rf"{name}, $\mu$ = {mu:g}")
    ax5[0, 1].set_xlabel(r"$\kappa$")
    ax5[0, 1].set_ylabel(r"$\phi_{max}$")
    ax5[0, 1].set_title(r"fitted $\phi_{max}(\kappa)$")
    ax5[0, 1].legend(fontsize=7)
    written.append(plots.save_figure(fig5, target / "fig5_single_particle.png"))
    return written


def _fmt(x, digits=3) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "–"
    return f"{x:.{digits}f}" if isinstance(x, float) else str(x)


def run_times(w: Path) -> dict:
    """{name: wall seconds of the dispatches that ran it (summed over resumptions)}."""
    times = {}
    log = w / "dispatch.jsonl"
    if log.is_file():
        for line in log.read_text().splitlines():
            entry = json.loads(line)
            if entry["status"] in ("complete", "incomplete", "killed", "failed"):
                times[entry["name"]] = times.get(entry["name"], 0.0) + entry.get("wall_time", 0.0)
    return times


def summary_markdown(w: Path, study: dict, result: dict) -> str:
    law, groups, glob = result["law"], result["groups"], result["coordination_all"]
    times = run_times(w)
    lines = [f"# Mixture compaction: N = {study['n']}, {study['element']} x {study['elements']} elements, "
             f"P/E = {', '.join(f'{p:.3g}' for p in study['pressures_over_E'])}", "",
             f"Z column: `{result['z_column']}`. b = {law['b']:.4g}, phi_p,max = {law['phi_p_max']:.4g} from: {law['source']}.", ""]
    lines += ["| κ | μ | seeds | φ₀ ± seed std (paper) | Z₀ ± seed std (paper) | ξ, α (group) | φ_max Eq. 5 (± seed std) | φ_max Platzer (± seed std) | P₀/E | "
              "Eq. 5 err φ rms / max | Platzer err φ rms / max | Eq. 3 err K rms (φ_max(κ) / φ_p,max) | run time s |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for (kappa, mu), g in sorted(groups.items()):
        e = g["errors"]
        co, e5, pl = g["coordination"], g["eq5"], g["platzer"]
        t = sum(times.get(r["name"], 0.0) for r in study["runs"] if r["kappa"] == kappa and r["mu"] == mu)
        std = f" ± {g['phi0_std']:.3f}" if math.isfinite(g["phi0_std"]) else ""
        zstd = f" ± {g['Z0_std']:.2f}" if math.isfinite(g["Z0_std"]) else ""

        def pm(key):
            v = g.get(f"{key}_phi_max_seed_std", np.nan)
            return f" ± {v:.3f}" if math.isfinite(v) else ""

        lines.append(
            f"| {kappa:g} | {mu:g} | {len(g['seeds'])} | {g['phi0']:.3f}{std} ({PAPER_PHI0.get(mu, {}).get(kappa, '–')}) | "
            f"{g['Z0']:.2f}{zstd} ({PAPER_Z0.get(mu, {}).get(kappa, '–')}) | "
            + (f"{co.params['xi']:.2f}, {co.params['alpha']:.2f}" if co else "–") + " | "
            + (f"{e5.params['phi_max']:.4f}{pm('eq5')}" if e5 else "–") + " | "
            + (f"{pl.params['phi_max']:.4f}{pm('platzer')}" if pl else "–") + " | "
            + (f"{pl.params['P0']:.3g}" if pl else "–")
            + f" | {_fmt(e['eq5_phi_rms'], 4)} / {_fmt(e['eq5_phi_max_abs'], 4)} | {_fmt(e['platzer_phi_rms'], 4)} / "
              f"{_fmt(e['platzer_phi_max_abs'], 4)} | {_fmt(e['eq3_rms_rel'], 2)} / {_fmt(e['eq3_single_rms_rel'], 2)} | {t:.0f} |")
    lines += ["", "| over all runs | toolkit | paper |", "|---|---|---|",
              f"| ξ | {_fmt(glob.params['xi'], 2) if glob else '–'} | {PAPER_XI} |",
              f"| α | {_fmt(glob.params['alpha'], 2) if glob else '–'} | {PAPER_ALPHA} |",
              f"| b | {law['b']:.3g}{' (the paper’s value, not measured)' if law['paper_default'] else ''} | {PAPER_B} |", ""]
    total = sum(times.values())
    lines.append(f"Compute wall time summed over runs: {total:.0f} s; pre: {study.get('pre_seconds', float('nan'))} s.")
    unfinished = [(r["name"], run_status(w / r["out"])) for r in study["runs"]]
    unfinished = [(name, st) for name, st in unfinished if st != "complete"]
    if unfinished:
        lines += ["", "Runs not COMPLETE (their numbers above are not what their scenes asked for):"]
        for name, st in unfinished:
            reason = next((w / r["out"] / st.upper() for r in study["runs"] if r["name"] == name), None)
            detail = reason.read_text().strip().replace("\n", "; ") if reason is not None and reason.is_file() else ""
            lines.append(f"- {name}: {st}" + (f" ({detail})" if detail else ""))
    if result["notes"]:
        lines += ["", "Notes:"] + [f"- {n}" for n in result["notes"]]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--workdir", required=True, help="study folder (DIR/study.json, DIR/runs/*/out); writes DIR/post")
    p.add_argument("--b", type=float, default=None, help="b of Eq. 2 (default: single-particle result, else 0.14)")
    p.add_argument("--phi-p-max", type=float, default=None, help="phi_p,max of Eq. 2 (for Eq. 3)")
    p.add_argument("--single-particle", default=None, metavar="PATH",
                   help="single-particle result: JSON with b and phi_p_max, a measures.csv, or a study folder")
    p.add_argument("--z-column", choices=Z_COLUMNS, default="Z",
                   help="coordination number used (post.measures; default Z = 2 N_c / N_p, all particles)")
    p.add_argument("--xi-alpha", choices=("all", "group"), default="all",
                   help="xi, alpha of Eq. 5: fitted over all runs (default, as the paper) or per (kappa, mu)")
    p.add_argument("--threshold", type=float, default=1e-9, help="active contacts: fn > T x mean fn (default 1e-9)")
    a = p.parse_args(argv)
    os.environ.setdefault("MPLBACKEND", "Agg")

    w = Path(a.workdir)
    study = json.loads((w / "study.json").read_text())
    law = single_particle_law(a, study)
    print(f"b = {law['b']:.4g}, phi_p,max = {law['phi_p_max']:.4g}: {law['source']}")
    tables = measure_runs(w, study, a.threshold)
    if not tables:
        print("no run has output yet: nothing to analyse", file=sys.stderr)
        return 2
    result = analyse(study, tables, law, a.z_column, a.xi_alpha)
    target = w / "post"
    target.mkdir(parents=True, exist_ok=True)
    g = result["groups"]
    written = [
        write_csv(target / "table1.csv", [{k: v[k] for k in ("kappa", "mu", "phi0", "phi0_std", "Z0", "Z0_std", "n_points")}
                                          | {"n_seeds": len(v["seeds"]), "phi0_paper": PAPER_PHI0.get(v["mu"], {}).get(v["kappa"], ""),
                                             "Z0_paper": PAPER_Z0.get(v["mu"], {}).get(v["kappa"], "")}
                                          for v in g.values()]),
        write_csv(target / "fits.csv", result["fit_rows"]),
        write_csv(target / "errors.csv", [v["errors"] for v in g.values()]),
        write_csv(target / "curves.csv", result["points"]),
    ]
    written += figures(w, study, result, target)
    (target / "summary.md").write_text(summary_markdown(w, study, result))
    written.append(target / "summary.md")
    (target / "single_particle_law.json").write_text(json.dumps(law, indent=1) + "\n")
    print("\n".join(map(str, written)))
    for note in result["notes"]:
        print(f"note: {note}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
