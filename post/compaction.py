"""The paper's analysis of a compaction study: pooling over seeds, the fits and their errors, the
Eq. 3 check, the study tables — for any set of runs, the toolkit's or a user's own.

Input: a study description (``study.json`` written by the mixture study's pre stage, or a dict
with the same keys: ``runs`` = [{name, kappa, mu, seed, out}], optional ``young``) and the per-run
measures tables (:func:`measure_runs`, post.table). Output: a :class:`Compaction` record.

- Table 1: φ₀, Z₀ per (κ, μ), averaged over seeds, of each run's prepared sample (its
  ``prepared`` values in the study: the packing before any load) or of its first equilibrated
  frame (``phi0`` of :func:`analyse`); both are in the table.
- Platzer et al.: P(φ) = P₀ ln[(φ_max − φ₀)/(φ_max − φ)] per (κ, μ).
- Eq. 5 (the paper's compaction law) with φ_max its only free parameter: b of Eq. 2 (the single
  particle), ξ, α of Z − Z₀ = ξ (φ − φ₀)^α (fitted over all runs, or per (κ, μ)), φ₀, Z₀.
- Errors of Eq. 5 and Platzer on the points, in φ at given P and in P at given φ.
- Eq. 3: K against Z φ K_p / 2π, K_p = b φ / (φ_max − φ) the single particle's modulus "at
  equivalent packing fraction", with φ_max(κ) of the Eq. 5 fit and with φ_p,max.
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from post import fits, rounding

FIT_COLUMNS = ["law", "kappa", "mu", "parameter", "value", "stderr", "phi_min", "phi_max_fitted", "rms",
               "rms_relative"]
ERROR_KEYS = ("phi_rms", "phi_max_abs", "P_rms_rel", "P_max_rel")
# the numbers fitted to each seed alone, whose scatter between seeds Table 1 shows beside the pooled fits
SEED_KEYS = ("xi", "alpha", "eq5_phi_max", "platzer_phi_max", "platzer_P0", "eq5_phi_rms", "platzer_phi_rms")


@dataclass(frozen=True)
class Reference:
    """Published values to compare with: φ₀ and Z₀ as {μ: {κ: value}}, ξ, α and b."""

    phi0: dict
    Z0: dict
    xi: float
    alpha: float
    b: float


@dataclass(frozen=True)
class SingleParticleLaw:
    """Eq. 2's b and φ_p,max, where they come from, and whether b is the paper's value (no
    single-particle result of the toolkit was found)."""

    b: float
    phi_p_max: float
    source: str
    paper_default: bool = False


@dataclass
class Group:
    """One (κ, μ): its points pooled over seeds and what was fitted to them.

    phi, P, Z, K (n,): the equilibrated points (P and K over E); phi0, Z0 (of the study's Z column)
    and Z0_no_rattlers averaged over the seeds (``*_std``: their scatter, NaN with one seed), the
    ones the fits use; ``phi0_prepared``, ``Z0_prepared`` and ``phi0_first_stage``,
    ``Z0_first_stage``: both readings, seed-averaged (NaN where the study has no prepared values);
    platzer, coordination, eq5: post.fits results (None when a fit failed, see Compaction.notes);
    seed_std: the scatter between seeds of every fitted number (:data:`SEED_KEYS`), each seed's
    points fitted alone; eq3, eq3_single (n,): the Eq. 3 predictions of K/E; errors: the row of
    errors.csv."""

    kappa: float
    mu: float
    seeds: list
    phi: np.ndarray
    P: np.ndarray
    Z: np.ndarray
    K: np.ndarray
    phi0: float
    Z0: float
    phi0_std: float
    Z0_std: float
    Z0_no_rattlers: float = np.nan
    Z0_no_rattlers_std: float = np.nan
    phi0_prepared: float = np.nan
    Z0_prepared: float = np.nan
    phi0_first_stage: float = np.nan
    Z0_first_stage: float = np.nan
    xi_alpha: tuple[float, float] = (np.nan, np.nan)
    platzer: fits.FitResult | None = None
    coordination: fits.FitResult | None = None
    eq5: fits.FitResult | None = None
    seed_std: dict = field(default_factory=dict)  # {SEED_KEYS item: scatter of the per-seed fits}, NaN with one seed
    eq3: np.ndarray | None = None
    eq3_single: np.ndarray | None = None
    errors: dict = field(default_factory=dict)


@dataclass
class Compaction:
    """The analysis of a study: ``groups`` by (κ, μ), ``points`` (rows of curves.csv),
    ``fit_rows`` (rows of fits.csv), the coordination law over all runs, the notes on what
    could not be fitted, ``phi0_from``: "prepared" or "first-stage", where φ₀, Z₀ come from, and
    the scatter of ξ, α fitted over all runs of each seed alone (NaN with one seed, or when the
    (κ, μ) do not all have the same seeds)."""

    law: SingleParticleLaw
    z_column: str
    groups: dict[tuple[float, float], Group]
    points: list[dict]
    fit_rows: list[dict]
    coordination_all: fits.FitResult | None
    notes: list[str]
    phi0_from: str = "first-stage"
    coordination_all_seed_std: dict = field(default_factory=dict)  # {"xi", "alpha": scatter of the per-seed fits}

    def table1(self, paper_phi0: dict | None = None, paper_Z0: dict | None = None) -> list[dict]:
        """Rows of table1.csv: φ₀, Z₀ (the study's Z column) and Z₀ without rattlers, with their seed
        scatter, per (κ, μ), as the fits use them (``phi0_from``), and both readings (prepared,
        first stage), with the paper's values ({μ: {κ: value}}) when given."""
        rows = []
        for g in self.groups.values():
            rows.append({"kappa": g.kappa, "mu": g.mu, "phi0": g.phi0, "phi0_std": g.phi0_std, "Z0": g.Z0,
                         "Z0_std": g.Z0_std, "Z0_no_rattlers": g.Z0_no_rattlers,
                         "Z0_no_rattlers_std": g.Z0_no_rattlers_std, "phi0_from": self.phi0_from,
                         "phi0_prepared": g.phi0_prepared, "Z0_prepared": g.Z0_prepared,
                         "phi0_first_stage": g.phi0_first_stage, "Z0_first_stage": g.Z0_first_stage,
                         "n_points": len(g.phi), "n_seeds": len(g.seeds),
                         "phi0_paper": (paper_phi0 or {}).get(g.mu, {}).get(g.kappa, ""),
                         "Z0_paper": (paper_Z0 or {}).get(g.mu, {}).get(g.kappa, "")})
        return rows


# ------------------------------------------------------------------------------ inputs


def law_from_file(path: Path, element: str, elements: int) -> SingleParticleLaw:
    """b and φ_p,max from a single-particle result: a JSON file with "b" and "phi_p_max"; a CSV
    table of fits per mesh (columns element, elements, b, phi_p_max: the row of ``element`` with
    the closest number of ``elements``, uniform meshes first); or a single-particle measures.csv
    (Eq. 2 fitted here)."""
    path = Path(path)
    if path.suffix == ".json":
        data = json.loads(path.read_text())
        if not all(isinstance(data.get(k), (int, float)) for k in ("b", "phi_p_max")):
            raise ValueError(f"{path}: expected numbers 'b' and 'phi_p_max'")
        rng = data.get("phi_range")
        where = f" (phi_p in [{rng[0]:.4f}, {rng[1]:.4f}])" if isinstance(rng, list) and len(rng) == 2 else ""
        return SingleParticleLaw(float(data["b"]), float(data["phi_p_max"]), f"{path}{where}")
    with path.open(newline="") as stream:
        rows = list(csv.DictReader(stream))
    if rows and {"b", "phi_p_max", "element", "elements"} <= set(rows[0]):  # a table of fits per mesh
        uniform = [r for r in rows if not r.get("boundary_segments")] or rows  # the study's meshes are uniform
        same = [r for r in uniform if r["element"] == element] or uniform
        row = min(same, key=lambda r: abs(int(r["elements"]) - elements))
        return SingleParticleLaw(float(row["b"]), float(row["phi_p_max"]),
                                 f"{path}, row {row['element']} x {row['elements']} elements "
                                 f"(phi_p in [{float(row['phi_min']):.4f}, {float(row['phi_max']):.4f}])")
    from post.table import read_measures

    m = read_measures(path)
    keep = m["equilibrated"].astype(bool) if "equilibrated" in m.dtype.names else np.ones(len(m), bool)
    pressure = m["P_walls"] if "P_walls" in m.dtype.names else m["pressure_applied"]
    fit = fits.fit_single_particle(m["phi"][keep], pressure[keep])
    return SingleParticleLaw(fit.params["b"], fit.params["phi_p_max"],
                             f"Eq. 2 fitted to {path} (phi_p in [{fit.phi_range[0]:.4f}, {fit.phi_range[1]:.4f}])")


def measure_runs(workdir: Path, study: dict, threshold: float = 1e-9, log: Callable[[str], None] = print) -> dict:
    """Write every run's out/post/measures.csv (post.table); return {name: rows} of the runs that
    have frames. Runs without output, or with unreadable output, are left out (and said so). A
    frame whose files are gone keeps its row of the run's earlier measures.csv (a run resumed on
    another machine from its small files, post.table.measure_output)."""
    from compute import files
    from compute.summary import run_status
    from compute.output import read_frame_rows
    from post import measures
    from post.errors import OutputError
    from post.table import measure_output, write_measures

    tables = {}
    for run in study["runs"]:
        out = Path(workdir) / run["out"]
        try:
            if not files.is_file(out / "frames.csv", OutputError):
                log(f"  {run['name']}: no output yet, left out")
                continue
            if not read_frame_rows(out / "frames.csv", OutputError):  # the header alone: no stage ended yet
                log(f"  {run['name']}: no frame yet ({run_status(out)}), left out")
                continue
            rows = measure_output(out, measures.default_min_contacts(run["mu"]), threshold,
                                  kept=out / "post" / "measures.csv")
        except OutputError as exc:
            log(f"  {run['name']}: unreadable output, left out ({exc})")
            continue
        write_measures(rows, out / "post" / "measures.csv")
        log(f"  {run['name']}: {len(rows)} frames ({run_status(out)})")
        tables[run["name"]] = rows
    return tables


# ------------------------------------------------------------------------------ analysis


def phi_of_pressure(model, pressure: np.ndarray, phi0: float, phi_max: float) -> np.ndarray:
    """Invert a law P(φ) increasing on (φ₀, φ_max) from 0 to ∞: φ (n,) at the pressures (n,)
    (NaN where no root is bracketed)."""
    from scipy.optimize import brentq

    out = np.full(len(pressure), np.nan)
    hi = phi_max - 1e-12 * max(1.0, phi_max)
    for k, p in enumerate(pressure):
        try:
            out[k] = brentq(lambda x: model(np.array([x]))[0] - p, phi0, hi, xtol=1e-14)
        except ValueError:
            pass
    return out


def law_errors(model, phi: np.ndarray, pressure: np.ndarray, phi0: float, phi_max: float) -> dict:
    """Errors of a fitted law P(φ) on the points (φ, P) (n,): in φ at given P (|φ_model(P) − φ|,
    RMS and max) and in P at given φ (P_model(φ)/P − 1 over the points above φ₀, RMS and max)."""
    dphi = phi_of_pressure(model, pressure, phi0, phi_max) - phi
    above = phi > phi0 + 1e-12  # the law gives P = 0 at phi0 itself: no relative error there
    rel = model(phi[above]) / pressure[above] - 1 if above.any() else np.array([np.nan])
    return {"phi_rms": float(np.sqrt(np.nanmean(dphi**2))), "phi_max_abs": float(np.nanmax(np.abs(dphi))),
            "P_rms_rel": float(np.sqrt(np.mean(rel**2))), "P_max_rel": float(np.max(np.abs(rel)))}


def _fit_row(law, kappa, mu, parameter, fit=None, value=None, shift=0.0) -> dict:
    """A row of fits.csv: ``parameter`` of ``fit`` (NaNs for a failed fit), or a plain ``value``.
    The coordination fits run on 1 + φ − φ₀, reported as φ − φ₀ (``shift``)."""
    if value is not None:
        return {"law": law, "kappa": kappa, "mu": mu, "parameter": parameter, "value": value, "stderr": np.nan,
                "phi_min": np.nan, "phi_max_fitted": np.nan, "rms": np.nan, "rms_relative": np.nan}
    return {"law": law, "kappa": kappa, "mu": mu, "parameter": parameter,
            "value": fit.params.get(parameter, fit.fixed.get(parameter)) if fit else np.nan,
            "stderr": fit.stderr.get(parameter, 0.0) if fit else np.nan,
            "phi_min": fit.phi_range[0] - shift if fit else np.nan,
            "phi_max_fitted": fit.phi_range[1] - shift if fit else np.nan,
            "rms": fit.rms if fit else np.nan, "rms_relative": fit.rms_relative if fit else np.nan}


def phi0_source(study: dict, tables: dict, phi0: str | None = None) -> str:
    """Where φ₀, Z₀ come from: ``phi0`` ("prepared": each run's ``prepared`` values in the study,
    measured on the sample before any load; "first-stage": its first equilibrated frame), or by
    default "prepared" when every run of ``tables`` has them, else "first-stage" (a study written
    before they were recorded). Asking "prepared" of a study without them is a ValueError."""
    missing = [r["name"] for r in study["runs"] if r["name"] in tables and not r.get("prepared")]
    if phi0 == "prepared" and missing:
        raise ValueError(f"field 'prepared' (phi0, Z0 of the prepared sample, written by the mixture study's "
                         f"pre.py) missing from runs {', '.join(missing)}: use the first stage")
    if phi0 not in (None, "prepared", "first-stage"):
        raise ValueError(f"phi0: expected 'prepared' or 'first-stage', got {phi0!r}")
    return phi0 or ("first-stage" if missing else "prepared")


def _points(study: dict, tables: dict, z_column: str, phi0: str = "first-stage") -> list[dict]:
    """One row per equilibrated frame of every run, with its run's φ₀, Z₀ (``phi0``: "prepared"
    or "first-stage", :func:`phi0_source`) and both readings of them."""
    young = float(study.get("young", 1.0))
    by_name = {r["name"]: r for r in study["runs"]}
    points = []
    for name, rows in tables.items():
        run = by_name[name]
        eq = [r for r in rows if r["equilibrated"]]
        prepared = run.get("prepared") or {}
        first = {"phi0": eq[0]["phi"], "Z0": eq[0][z_column], "Z0_no_rattlers": eq[0]["Z_no_rattlers"]} if eq else {}
        ready = {"phi0": prepared.get("phi", np.nan), "Z0": prepared.get(z_column, np.nan),
                 "Z0_no_rattlers": prepared.get("Z_no_rattlers", np.nan)}
        for r in eq:
            points.append({"name": name, "kappa": run["kappa"], "mu": run["mu"], "seed": run["seed"],
                           "stage": int(r["stage"]), "P_over_E": r["P"] / young, "P_walls_over_E": r["P_walls"] / young,
                           "pressure_applied": r["pressure_applied"], "phi": r["phi"], "Z": r[z_column],
                           "K_over_E": r["K"] / young, **(ready if phi0 == "prepared" else first),
                           "phi0_prepared": ready["phi0"], "Z0_prepared": ready["Z0"],
                           "phi0_first_stage": first["phi0"], "Z0_first_stage": first["Z0"]})
    return points


def analyse(study: dict, tables: dict, law: SingleParticleLaw, z_column: str = "Z", xi_alpha: str = "all",
            fallback_xi_alpha: tuple[float, float] = (5.1, 0.5), phi0: str | None = None) -> Compaction:
    """The analysis of the per-run measures ``tables`` ({run name: rows}) of ``study`` (module
    docstring). ``xi_alpha``: "all" (ξ, α of Eq. 5 fitted over all runs, as the paper) or
    "group" (per (κ, μ)); ``fallback_xi_alpha`` where that fit fails (default: the paper's);
    ``phi0``: where φ₀, Z₀ come from (:func:`phi0_source`; default prepared when every run has it)."""
    phi0_from = phi0_source(study, tables, phi0)
    points = _points(study, tables, z_column, phi0_from)
    notes: list[str] = []
    fit_rows: list[dict] = []

    def attempt(what, f):
        try:
            return f()
        except (ValueError, RuntimeError, TypeError) as exc:
            notes.append(f"{what}: not fitted ({exc})")
            return None

    # Z - Z0 = xi (phi - phi0)^alpha over all runs (each with its own phi0, Z0): shift to phi0 = 1, Z0 = 0
    dphi = np.array([p["phi"] - p["phi0"] for p in points])
    dZ = np.array([p["Z"] - p["Z0"] for p in points])
    glob = attempt("coordination law over all runs", lambda: fits.fit_coordination(1.0 + dphi, dZ, 1.0, 0.0))
    fit_rows += [_fit_row("coordination", "all", "all", n, glob, shift=1.0) for n in ("xi", "alpha")]
    seeds = np.array([p["seed"] for p in points])
    # over all runs, per seed: only when every (κ, μ) has the same seeds (else each seed's fit
    # would cover other groups, and its scatter would mix the groups' differences in)
    group_seeds: dict = {}
    for p in points:
        group_seeds.setdefault((p["kappa"], p["mu"]), set()).add(p["seed"])
    same = len({frozenset(v) for v in group_seeds.values()}) == 1
    per_seed = [attempt(f"coordination law over all runs of seed {s}",
                        lambda: fits.fit_coordination(1.0 + dphi[seeds == s], dZ[seeds == s], 1.0, 0.0))
                for s in (sorted(set(seeds.tolist())) if same and len(set(seeds.tolist())) > 1 else [])]
    glob_std = {n: _sample_std([f.params[n] for f in per_seed if f is not None]) for n in ("xi", "alpha")}
    fit_rows += [_fit_row("per seed", "all", "all", f"{n} std", value=v) for n, v in glob_std.items()]

    groups = {}
    for kappa, mu in sorted({(p["kappa"], p["mu"]) for p in points}):
        sel = [p for p in points if p["kappa"] == kappa and p["mu"] == mu]
        g = _group(kappa, mu, sel)
        tag = f"kappa {kappa:g}, mu {mu:g}"
        g.platzer = attempt(f"Platzer ({tag})", lambda: fits.fit_platzer(g.phi, g.P, g.phi0))
        fit_rows += [_fit_row("platzer", kappa, mu, n, g.platzer) for n in ("P0", "phi_max")]
        d_phi = np.array([p["phi"] - p["phi0"] for p in sel])
        d_Z = np.array([p["Z"] - p["Z0"] for p in sel])
        g.coordination = attempt(f"coordination ({tag})", lambda: fits.fit_coordination(1.0 + d_phi, d_Z, 1.0, 0.0))
        fit_rows += [_fit_row("coordination", kappa, mu, n, g.coordination, shift=1.0) for n in ("xi", "alpha")]
        source = g.coordination if xi_alpha == "group" else glob
        g.xi_alpha = (source.params["xi"], source.params["alpha"]) if source else fallback_xi_alpha
        if source is None:
            notes.append(f"Eq. 5 ({tag}): xi, alpha = {fallback_xi_alpha[0]}, {fallback_xi_alpha[1]} (fallback)")
        xi, alpha = g.xi_alpha
        g.eq5 = attempt(f"Eq. 5 ({tag})", lambda: fits.fit_eq5(g.phi, g.P, law.b, xi, alpha, g.Z0, g.phi0))
        fit_rows.append(_fit_row("eq5", kappa, mu, "phi_max", g.eq5))
        per_seed = []
        for seed in g.seeds if len(g.seeds) > 1 else []:
            mine = [p for p in sel if p["seed"] == seed]
            x, y, z = (np.array([p[k] for p in mine]) for k in ("phi", "P_over_E", "Z"))
            per_seed.append(run_fits(x, y, z, mine[0]["phi0"], mine[0]["Z0"], law.b, (xi, alpha),
                                     lambda what, f, s=seed: attempt(f"{what} ({tag}, seed {s})", f)))
        g.seed_std = {k: _sample_std([d[k] for d in per_seed]) for k in SEED_KEYS}
        fit_rows += [_fit_row("per seed", kappa, mu, f"{k} std", value=v) for k, v in g.seed_std.items()]
        _errors_and_eq3(g, law)
        for p, e5, e3, e3s in zip(sel, g.eq5.predict(g.phi) if g.eq5 else np.full(len(sel), np.nan), g.eq3,
                                  g.eq3_single):
            p["eq5_P_over_E"], p["eq3_K_over_E"], p["eq3_single_K_over_E"] = float(e5), float(e3), float(e3s)
            p["platzer_P_over_E"] = float(g.platzer.predict(np.array([p["phi"]]))[0]) if g.platzer else np.nan
        groups[(kappa, mu)] = g
    fit_rows.append(_fit_row("single_particle (Eq. 2)", "all", "all", "b", value=law.b))
    fit_rows.append(_fit_row("single_particle (Eq. 2)", "all", "all", "phi_p_max", value=law.phi_p_max))
    return Compaction(law, z_column, groups, points, fit_rows, glob, notes, phi0_from, glob_std)


def run_fits(phi: np.ndarray, P: np.ndarray, Z: np.ndarray, phi0: float, Z0: float, b: float,
             xi_alpha: tuple[float, float] | None = None, attempt=None) -> dict:
    """{SEED_KEYS item: value} of one run's (or one seed's) points φ, P/E, Z (n,) fitted alone
    from φ₀, Z₀: ξ, α of Z − Z₀ = ξ (φ − φ₀)^α; Eq. 5's φ_max with Eq. 2's ``b`` and
    ``xi_alpha`` (default: the ξ, α just fitted); Platzer's φ_max and P₀; both laws' rms error in
    φ (:func:`law_errors`). NaN where a fit failed; ``attempt(what, f)`` runs each fit and returns
    None on failure (default: quietly)."""
    attempt = attempt or _quietly
    out = dict.fromkeys(SEED_KEYS, np.nan)
    co = attempt("coordination", lambda: fits.fit_coordination(1.0 + phi - phi0, Z - Z0, 1.0, 0.0))
    if co:
        out["xi"], out["alpha"] = co.params["xi"], co.params["alpha"]
    xi, alpha = xi_alpha or (out["xi"], out["alpha"])
    e5 = attempt("Eq. 5", lambda: fits.fit_eq5(phi, P, b, xi, alpha, Z0, phi0)) if np.isfinite(xi) else None
    pl = attempt("Platzer", lambda: fits.fit_platzer(phi, P, phi0))
    for key, fit in (("eq5", e5), ("platzer", pl)):
        if fit:
            out[f"{key}_phi_max"] = fit.params["phi_max"]
            out[f"{key}_phi_rms"] = law_errors(fit.predict, phi, P, phi0, fit.params["phi_max"])["phi_rms"]
    if pl:
        out["platzer_P0"] = pl.params["P0"]
    return out


def _quietly(what: str, f):
    """f(), or None where the fit fails."""
    try:
        return f()
    except (ValueError, RuntimeError, TypeError):
        return None


def _sample_std(values) -> float:
    """The sample standard deviation of the finite ``values`` (NaN below two)."""
    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    return float(np.std(v, ddof=1)) if v.size > 1 else np.nan


def _group(kappa: float, mu: float, sel: list[dict]) -> Group:
    seeds = sorted({p["seed"] for p in sel})

    def over_seeds(key: str) -> tuple[float, float]:
        """Mean over the seeds of a run-level value, and its scatter (NaN with one seed)."""
        x = np.array([next(p[key] for p in sel if p["seed"] == s) for s in seeds])
        return float(x.mean()), float(x.std(ddof=1)) if len(seeds) > 1 else np.nan

    (phi0, phi0_std), (Z0, Z0_std), (Z0_nr, Z0_nr_std) = (over_seeds(k) for k in ("phi0", "Z0", "Z0_no_rattlers"))
    readings = {k: over_seeds(k)[0] for k in ("phi0_prepared", "Z0_prepared", "phi0_first_stage", "Z0_first_stage")}
    return Group(kappa, mu, seeds, phi=np.array([p["phi"] for p in sel]), P=np.array([p["P_over_E"] for p in sel]),
                 Z=np.array([p["Z"] for p in sel]), K=np.array([p["K_over_E"] for p in sel]),
                 phi0=phi0, Z0=Z0, phi0_std=phi0_std, Z0_std=Z0_std, Z0_no_rattlers=Z0_nr,
                 Z0_no_rattlers_std=Z0_nr_std, **readings)


def _errors_and_eq3(g: Group, law: SingleParticleLaw) -> None:
    """The errors of Eq. 5 and Platzer on the group's points, and the Eq. 3 check of K with
    φ_max(κ) of Eq. 5 ("eq3") and with the single particle's φ_p,max ("eq3_single")."""
    err = {"kappa": g.kappa, "mu": g.mu, "n_points": len(g.phi)}
    for key, fit in (("eq5", g.eq5), ("platzer", g.platzer)):
        e = law_errors(fit.predict, g.phi, g.P, g.phi0, fit.params["phi_max"]) if fit else {}
        for k in ERROR_KEYS:
            err[f"{key}_{k}"] = e.get(k, np.nan)
    finite = np.isfinite(g.K) & (g.K > 0)
    for key, top in (("eq3", g.eq5.params["phi_max"] if g.eq5 else np.nan), ("eq3_single", law.phi_p_max)):
        prediction = np.full(len(g.K), np.nan)
        err[f"{key}_rms_rel"] = err[f"{key}_max_rel"] = np.nan
        if finite.any() and np.isfinite(top) and top > g.phi.max():
            check = fits.eq3_check(g.phi[finite], g.K[finite], g.Z[finite], law.b, top)
            prediction[finite] = check.prediction
            err[f"{key}_rms_rel"] = check.rms_relative
            err[f"{key}_max_rel"] = float(np.max(np.abs(check.relative_error)))
        setattr(g, key, prediction)
    g.errors = err


# ------------------------------------------------------------------------------ outputs


def write_csv(path: Path, rows: list[dict], columns: list[str] | None = None) -> Path:
    """Rows as CSV (floats written with repr: no digit lost)."""
    if columns is None:
        columns = list(rows[0]) if rows else []
    with Path(path).open("w", newline="") as stream:
        writer = csv.DictWriter(stream, fieldnames=columns, extrasaction="ignore")
        writer.writeheader()
        for row in rows:
            writer.writerow({k: (repr(float(v)) if isinstance(v, (float, np.floating)) else v) for k, v in row.items()})
    return Path(path)


def write_tables(result: Compaction, target: Path, paper_phi0: dict | None = None,
                 paper_Z0: dict | None = None) -> list[Path]:
    """table1.csv, fits.csv, errors.csv and curves.csv in ``target``."""
    target.mkdir(parents=True, exist_ok=True)
    return [write_csv(target / "table1.csv", result.table1(paper_phi0, paper_Z0)),
            write_csv(target / "fits.csv", result.fit_rows, FIT_COLUMNS),
            write_csv(target / "errors.csv", [g.errors for g in result.groups.values()]),
            write_csv(target / "curves.csv", result.points)]


def summary_markdown(study: dict, result: Compaction, reference: Reference, times: dict | None = None,
                     statuses: dict | None = None, reasons: dict | None = None) -> str:
    """The study's numbers beside the ``reference`` ones: per (κ, μ) φ₀, Z₀ (± seed scatter), ξ,
    α, φ_max of Eq. 5 and Platzer, P₀, the errors; ξ, α, b over all runs; run times ({run name:
    seconds}), and the runs that are not complete ({name: status}, {name: reason}). Every number
    is rounded to its meaning (post.rounding): fitted values at their standard error."""
    law, groups, glob = result.law, result.groups, result.coordination_all
    times, statuses, reasons = times or {}, statuses or {}, reasons or {}
    lines = [f"# Mixture compaction: N = {study['n']}, {study['element']} x {study['elements']} elements, "
             f"P/E = {', '.join(rounding.significant(p) for p in study['pressures_over_E'])}", "",
             f"Z column: `{result.z_column}`. b = {rounding.significant(law.b, 4)}, "
             f"phi_p,max = {rounding.significant(law.phi_p_max, 4)} from: {law.source}.", "",
             "φ₀, Z₀: " + ("the prepared sample's (before any load; table1.csv also has the first stage's)"
                          if result.phi0_from == "prepared" else
                          "the first equilibrated stage's" + (" (table1.csv also has the prepared sample's)" if any(
                              math.isfinite(g.phi0_prepared) for g in result.groups.values()) else "")) + ".", ""]
    lines += ["With several seeds every ± is the scatter between seeds (sample standard deviation, each seed's "
              "points fitted alone); with one seed ξ, α and P₀ carry their fit's standard error.", "",
              "| κ | μ | seeds | φ₀ (paper) | Z₀ (paper) | Z₀ without rattlers | ξ, α (group) | "
              "φ_max Eq. 5 | φ_max Platzer | P₀/E | Eq. 5 err φ rms / max | "
              "Platzer err φ rms / max | Eq. 3 err K rms (φ_max(κ) / φ_p,max) | run time s |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]

    def fitted(fit, name, scatter=None, otherwise=rounding.significant, stderr=True):
        """The pooled fit's value ± the seed scatter, or ± its standard error (``stderr``) without one."""
        if not fit:
            return rounding.MISSING
        error = scatter if scatter is not None and math.isfinite(scatter) else (fit.stderr.get(name) if stderr else None)
        return rounding.with_error(fit.params[name], error, otherwise)

    def error(value, scatter):
        return (rounding.significant(value, 2) + (f" ± {rounding.significant(scatter, 1)}"
                                                  if scatter is not None and math.isfinite(scatter) else ""))

    for (kappa, mu), g in sorted(groups.items()):
        e, sd = g.errors, g.seed_std
        co, e5, pl = g.coordination, g.eq5, g.platzer
        t = sum(times.get(r["name"], 0.0) for r in study["runs"] if r["kappa"] == kappa and r["mu"] == mu)
        lines.append(
            f"| {kappa:g} | {mu:g} | {len(g.seeds)} | {rounding.with_error(g.phi0, g.phi0_std, rounding.phi)} "
            f"({reference.phi0.get(mu, {}).get(kappa, '–')}) | "
            f"{rounding.with_error(g.Z0, g.Z0_std, rounding.coordination)} ({reference.Z0.get(mu, {}).get(kappa, '–')}) | "
            f"{rounding.with_error(g.Z0_no_rattlers, g.Z0_no_rattlers_std, rounding.coordination)} | "
            + (f"{fitted(co, 'xi', sd.get('xi'))}, {fitted(co, 'alpha', sd.get('alpha'))}" if co else rounding.MISSING)
            + f" | {fitted(e5, 'phi_max', sd.get('eq5_phi_max'), rounding.phi, False)} | "
              f"{fitted(pl, 'phi_max', sd.get('platzer_phi_max'), rounding.phi, False)} | "
              f"{fitted(pl, 'P0', sd.get('platzer_P0'))} | "
              f"{error(e['eq5_phi_rms'], sd.get('eq5_phi_rms'))} / {rounding.significant(e['eq5_phi_max_abs'], 2)} | "
              f"{error(e['platzer_phi_rms'], sd.get('platzer_phi_rms'))} / "
              f"{rounding.significant(e['platzer_phi_max_abs'], 2)} | "
              f"{rounding.significant(e['eq3_rms_rel'], 2)} / {rounding.significant(e['eq3_single_rms_rel'], 2)} "
              f"| {rounding.duration(t)} |")
    lines += ["", "| over all runs | toolkit | paper |", "|---|---|---|",
              f"| ξ | {fitted(glob, 'xi', result.coordination_all_seed_std.get('xi'))} | {reference.xi} |",
              f"| α | {fitted(glob, 'alpha', result.coordination_all_seed_std.get('alpha'))} | {reference.alpha} |",
              f"| b | {rounding.significant(law.b)}{' (the paper’s value, not measured)' if law.paper_default else ''} "
              f"| {reference.b} |", ""]
    lines.append(f"Compute wall time summed over runs: {rounding.duration(sum(times.values()))} s; "
                 f"pre: {rounding.duration(study.get('pre_seconds'))} s.")
    unfinished = [(name, status) for name, status in statuses.items() if status != "complete"]
    if unfinished:
        lines += ["", "Runs not COMPLETE (their numbers above are not what their scenes asked for):"]
        lines += [f"- {name}: {status}" + (f" ({reasons[name]})" if reasons.get(name) else "") for name, status in unfinished]
    if result.notes:
        lines += ["", "Notes:"] + [f"- {n}" for n in result.notes]
    return "\n".join(lines) + "\n"
