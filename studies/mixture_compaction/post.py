"""Stage 3 of the mixture compaction study: measures of every run and the paper's analysis.

Per run: DIR/runs/<name>/out/post/measures.csv (post.table: φ, Z, stress from the contacts, P from
contacts and from walls, K = φ dP/dφ on the equilibrated frames).

Study level, in DIR/post/ (equilibrated frames only; seeds of one (κ, μ) pooled):
- table1.csv: φ₀, Z₀ per (κ, μ), the paper's Table 1: by default the prepared sample's (the runs'
  "prepared" values in study.json, before any load), else, and with --phi0 first-stage, the first
  equilibrated stage's (P/E = p_min); the columns phi0_prepared, Z0_prepared, phi0_first_stage,
  Z0_first_stage give both, phi0_from which one the fits use;
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

if not __package__:  # run as a file (python studies/X/stage.py): studies/entry.py
    import pathlib, sys; sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2]))
    from studies.entry import run_as_file; run_as_file(__file__)

import argparse
import json
import os
import sys
from pathlib import Path

from compute.summary import run_status
from studies.dispatch import run_times
from post import compaction, plots
from post.compaction import Reference, SingleParticleLaw

REPO = Path(__file__).resolve().parents[2]
SINGLE_PARTICLE_CANDIDATES = ("studies/single_particle/results/refinement_fits.csv",
                              "studies/single_particle/results/fit.json")
ASSUMED_PHI_P_MAX = 1.0
Z_COLUMNS = ("Z", "Z_no_rattlers", "Z_bulk", "Z_constraints")
# Cárdenas-Barrantes et al. 2021, Table 1 (N = 1500), and the fits of Sec. 3
PAPER = Reference(phi0={0.0: {0.2: 0.815, 0.5: 0.811, 0.8: 0.807, 1.0: 0.807},
                        0.2: {0.2: 0.814, 0.5: 0.811, 0.8: 0.807, 1.0: 0.805}},
                  Z0={0.0: {0.2: 3.4, 0.5: 3.6, 0.8: 3.5, 1.0: 3.4}, 0.2: {0.2: 3.3, 0.5: 3.7, 0.8: 3.5, 1.0: 3.5}},
                  xi=5.1, alpha=0.5, b=0.14)


def single_particle_law(args, study: dict) -> SingleParticleLaw:
    """b and phi_p,max in the order of the module docstring."""
    phi_p_max = args.phi_p_max or ASSUMED_PHI_P_MAX
    if args.b is not None:
        return SingleParticleLaw(args.b, phi_p_max, "command line (--b)"
                                 + ("" if args.phi_p_max else f", phi_p_max assumed {ASSUMED_PHI_P_MAX}"))
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
        try:
            law = compaction.law_from_file(path, study.get("element", "T3"), int(study.get("elements", 92)))
        except ValueError as exc:
            raise SystemExit(str(exc)) from None
        source = law.source.replace(f"{REPO}/", "")  # the repository's files by their path in it, not this machine's
        return SingleParticleLaw(law.b, args.phi_p_max or law.phi_p_max, source)
    return SingleParticleLaw(PAPER.b, phi_p_max, f"PAPER'S VALUE b = {PAPER.b} (no single-particle result found), "
                             "phi_p_max " + (f"{args.phi_p_max} (--phi-p-max)" if args.phi_p_max
                                             else f"= {ASSUMED_PHI_P_MAX} assumed"), paper_default=True)


def views(w: Path, study: dict, result: compaction.Compaction):
    """Fig. 1: kappa = 0.5 (or the closest), the largest mu, at up to four equilibrated stages."""
    import numpy as np

    from post.frames import frame_path, read_frame, read_frames_table

    kappas, mus = sorted({k for k, _ in result.groups}), sorted({m for _, m in result.groups})
    k1, m1 = min(kappas, key=lambda k: abs(k - 0.5)), max(mus)
    run = next((r for r in study["runs"] if r["kappa"] == k1 and r["mu"] == m1
                and (w / r["out"] / "frames.csv").is_file()), None)
    if run is None:
        return None
    out = w / run["out"]
    records = [r for r in read_frames_table(out) if r.equilibrated]
    pick = [records[i] for i in sorted({round(x) for x in np.linspace(0, len(records) - 1, min(4, len(records)))})]
    gone = [r.frame for r in pick if not frame_path(out, "bodies", r.frame).is_file()]
    if gone:  # a study carried without its frames (its measures are kept): the figure stays as drawn
        print(f"fig1_views.png not redrawn: frames {gone} of {run['name']} are not in {out / 'frames'}")
        return None
    return plots.figure_views([read_frame(out, r) for r in pick],
                              f"kappa = {k1:g}, mu = {m1:g} (grey: rigid; colour: soft disk pressure p/E)",
                              float(study.get("young", 1.0)))


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
    p.add_argument("--phi0", choices=("prepared", "first-stage"), default=None,
                   help="phi0, Z0: of the prepared sample (default, when every run has it in study.json) or "
                        "of the first equilibrated stage (the default for a study without prepared values)")
    a = p.parse_args(argv)
    os.environ.setdefault("MPLBACKEND", "Agg")

    w = Path(a.workdir)
    study = json.loads((w / "study.json").read_text())
    law = single_particle_law(a, study)
    print(f"b = {law.b:.4g}, phi_p,max = {law.phi_p_max:.4g}: {law.source}")
    tables = compaction.measure_runs(w, study, a.threshold, log=lambda m: print(m, flush=True))
    if not tables:
        print("no run has output yet: nothing to analyse", file=sys.stderr)
        return 2
    try:
        phi0 = compaction.phi0_source(study, tables, a.phi0)
    except ValueError as exc:
        p.error(f"{w / 'study.json'}: {exc}")
    print(f"phi0, Z0: {phi0}")
    result = compaction.analyse(study, tables, law, a.z_column, a.xi_alpha, (PAPER.xi, PAPER.alpha), phi0)
    target = w / "post"
    written = compaction.write_tables(result, target, PAPER.phi0, PAPER.Z0)
    figures = {"fig1_views.png": views(w, study, result), "fig2_compaction.png": plots.figure_compaction(result),
               "fig3_bulk_modulus.png": plots.figure_bulk_modulus(result),
               "fig4_coordination.png": plots.figure_coordination(result, (PAPER.xi, PAPER.alpha)),
               "fig5_single_particle.png": plots.figure_single_particle_law(result)}
    written += [plots.save_figure(fig, target / name) for name, fig in figures.items() if fig is not None]
    statuses = {r["name"]: run_status(w / r["out"]) for r in study["runs"]}
    reasons = {name: (w / r["out"] / st.upper()).read_text().strip().replace("\n", "; ")
               for r in study["runs"] for name, st in [(r["name"], statuses[r["name"]])]
               if (w / r["out"] / st.upper()).is_file()}
    (target / "summary.md").write_text(compaction.summary_markdown(study, result, PAPER, run_times(w / "dispatch.jsonl"),
                                                                  statuses, reasons))
    (target / "single_particle_law.json").write_text(json.dumps(law.__dict__, indent=1) + "\n")
    print("\n".join(map(str, [*written, target / "summary.md"])))
    for note in result.notes:
        print(f"note: {note}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
