"""Single-particle study: run time against error, for meshes of about 30, 92, 300, 1000 elements,
T3 and T6 (both volumetric terms), and several time steps, all in one process, one after the other.

Each case is the single-particle study itself (studies/single_particle: pre.write, compute.main,
post.curve, imported, not copied) with its defaults except the element type, the volumetric
term, the element count and the time step h; it runs in a temporary folder. The run time is the
wall time of the study's compute stage (scene reading, model building and all the stages; not
the gmsh meshing nor post), after an untimed warm-up run per element type.

Errors against the converged refinement reference (studies/single_particle/data/
reference_T6g.csv, its first line says how it was made; its convergence is in
studies/single_particle/README.md, "Convergence"):

- err_phi: max |phi_run(P_ref) / phi_ref - 1| at the reference's pressure stages with
  phi_p <= 0.95 (P/E <= 0.16), phi_run interpolated linearly in ln P between the run's
  equilibrated stages (P = P_walls / E);
- err_P: max |P_run / P_ref(phi_run) - 1| over the run's equilibrated stages with phi_p <= 0.95
  inside the reference's phi range, P_ref(phi) interpolated linearly in ln P (P_p/E at equal phi_p);
- dphi: max |phi_run(P_ref) - phi_ref| at all the reference's stages (absolute);
- phi_end: phi_p at the run's last stage (P/E = 1).

Writes benchmarks/results/OUTPUT.{md,csv,png} (--output, default single_particle_cost).

    python benchmarks/single_particle_cost.py [--time-steps 10 5] [--elements 30 92 300 1000] [--graded 30:24 ...]
        [--volumetric standard mean_dilatation]
"""

from __future__ import annotations

import argparse
import csv
import io
import tempfile
import time
from pathlib import Path

import numpy as np

from compute.progress import Display

ROOT = Path(__file__).resolve().parent.parent
STUDY = ROOT / "studies" / "single_particle"
REFERENCE = STUDY / "data" / "reference_T6g.csv"
RESULTS = Path(__file__).resolve().parent / "results"
PHI_COMPARE = 0.95


def reference_comment() -> str:
    """The reference file's first line (how it was made), without the comment sign."""
    return REFERENCE.read_text().splitlines()[0].lstrip("# ")


def reference() -> tuple[np.ndarray, np.ndarray]:
    data = np.loadtxt(REFERENCE, delimiter=",", comments="#", skiprows=2)
    return data[:, 0], data[:, 1]


def run_case(work: Path, element: str, n: int, h: float, ref, segments: int | None = None,
             volumetric: str = "standard") -> dict:
    """One study run: ``n`` target elements (uniform), or ``segments`` boundary segments graded
    inward to the interior size of the ``n``-element mesh."""
    from compute.errors import SimulationError
    from compute.run import Run
    from post.single_particle import curve, curve_errors
    from pre.single_particle import write

    from pre.mesh import reference_disk_mesh

    d = work / f"{element}_{n}_b{segments}_h{h:g}_{volumetric}"
    write(d / "scene", element=element, elements=n, time_step=h, boundary_segments=segments, volumetric=volumetric)
    n_elements = len(reference_disk_mesh(n, element, segments).cells)
    t0 = time.perf_counter()
    run = Run(d / "scene", d / "out", log=lambda m: None, display=Display(1, stream=io.StringIO()))
    try:
        run.execute()
        status = "ok"
    except SimulationError as exc:
        status = f"failed ({exc})"
    seconds = time.perf_counter() - t0
    row = dict(element=element, volumetric=volumetric, elements=n_elements, boundary_segments=segments or "", h=h,
               status=status, seconds=seconds, steps=run.state.step,
               err_phi=np.nan, err_P=np.nan, dphi=np.nan, phi_end=np.nan, stages=0)
    try:
        _, p, phi = curve(d / "out")
        row["stages"] = len(p)
        row["err_phi"], row["err_P"] = curve_errors(p, phi, *ref, PHI_COMPARE)
        row["dphi"] = phi_difference(p, phi, *ref)
        row["phi_end"] = float(phi[np.argmax(p)])
    except Exception as exc:  # noqa: BLE001 - a failed case is reported, not fatal
        row["status"] += f"; post: {exc}"
    return row


def phi_difference(p: np.ndarray, phi: np.ndarray, p_ref: np.ndarray, phi_ref: np.ndarray) -> float:
    """max |φ_run − φ_ref| at the reference's pressures inside the run's range (all its stages,
    P/E <= 0.4), the run's curve interpolated in ln P."""
    from post.single_particle import phi_at

    inside, at = phi_at(p, phi, p_ref)
    return float(np.max(np.abs(at[inside] - phi_ref[inside])))


def plot(rows: list[dict], path: Path) -> None:
    from matplotlib.ticker import NullFormatter, ScalarFormatter

    from post.plots import new_figure, save_figure

    fig, axes = new_figure(1, 2, size=(5.0, 4.0))
    markers = {"T3": "s", "T6": "o"}
    styles = {"standard": "--", "mean_dilatation": "-"}
    hs = sorted({r["h"] for r in rows}, reverse=True)
    colors = dict(zip(hs, ["C0", "C1", "C2", "C3"]))
    for ax, key, title in zip(axes[0], ("err_phi", "err_P"),
                              (r"max rel. error of $\phi_p$ at equal $P$", r"max rel. error of $P_p/E$ at equal $\phi_p$")):
        for e, v in sorted({(r["element"], r["volumetric"]) for r in rows}):
            for h in hs:
                sub = sorted((r for r in rows if (r["element"], r["volumetric"]) == (e, v) and r["h"] == h
                              and np.isfinite(r[key])), key=lambda r: r["elements"])
                if not sub:
                    continue
                x, y = [r["seconds"] for r in sub], [r[key] for r in sub]
                ax.plot(x, y, marker=markers[e], color=colors[h], ls=styles[v], label=f"{e} {v}, h = {h:g}")
                for r in sub:
                    ax.annotate(str(r["elements"]), (r["seconds"], r[key]), fontsize=6,
                                textcoords="offset points", xytext=(3, 3))
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.xaxis.set_major_formatter(ScalarFormatter())
        ax.set_xlabel("run time (s)")
        ax.set_title(title + r", $\phi_p \leq 0.95$", fontsize=8)
        ax.legend(fontsize=7)
    save_figure(fig, path)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--elements", type=int, nargs="+", default=[30, 92, 300, 1000])
    ap.add_argument("--types", nargs="+", default=["T3", "T6"], choices=["T3", "T6"])
    ap.add_argument("--time-steps", type=float, nargs="+", default=[10.0, 5.0],
                    help="h in R sqrt(rho/E) (default: the study's 10 and 10/2; 20 stops at P/E = 0.63)")
    ap.add_argument("--skip", nargs="*", default=[], metavar="T6:1000:5",
                    help="element:elements:h combinations left out")
    ap.add_argument("--graded", nargs="*", default=[], metavar="N:B",
                    help="T6 meshes graded to B boundary segments, interior size of the N-element mesh")
    ap.add_argument("--volumetric", nargs="+", default=["standard"], choices=["standard", "mean_dilatation"],
                    help="volumetric terms of the T6 cases (default: the study's, standard); T3 is standard")
    ap.add_argument("--output", default="single_particle_cost", help="name of the result files in benchmarks/results")
    ap.add_argument("--plot-only", action="store_true", help="redraw the PNG from the CSV of the last run")
    a = ap.parse_args()
    if a.plot_only:
        rows = [dict(r, elements=int(r["elements"]), h=float(r["h"]), seconds=float(r["seconds"]),
                     err_phi=float(r["err_phi"]), err_P=float(r["err_P"]),
                     # records made before the volumetric column held the element's default then
                     volumetric=r.get("volumetric") or ("mean_dilatation" if r["element"] == "T6" else "standard"))
                for r in csv.DictReader(open(RESULTS / f"{a.output}.csv"))]
        plot(rows, RESULTS / f"{a.output}.png")
        return
    ref = reference()
    skip = {tuple(s.split(":")) for s in a.skip}
    rows = []
    RESULTS.mkdir(exist_ok=True)
    cols = ["element", "volumetric", "elements", "boundary_segments", "h", "status", "steps", "stages", "seconds", "err_phi", "err_P", "dphi", "phi_end"]
    t_all = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="sp_cost_") as tmp:
        for e in a.types:  # untimed warm-up: numba cache loading and imports, paid by the first run only
            run_case(Path(tmp) / "warmup", e, min(a.elements), a.time_steps[0], ref)
        volumetric = {"T3": ["standard"], "T6": a.volumetric}
        cases = [(e, n, h, None, v) for n in a.elements for e in a.types for h in a.time_steps for v in volumetric[e]
                 if (e, str(n), f"{h:g}") not in skip]
        cases += [("T6", int(g.split(":")[0]), h, int(g.split(":")[1]), v)
                  for g in a.graded for h in a.time_steps for v in a.volumetric]
        for e, n, h, segments, v in cases:
            rows.append(run_case(Path(tmp), e, n, h, ref, segments, v))
            r = rows[-1]
            print(f"{e} {r['volumetric']} {r['elements']:5d} (b {segments}) h={h:g}: {r['status']}, {r['steps']} steps, "
                  f"{r['seconds']:.1f} s, err_phi {r['err_phi']:.3g}, err_P {r['err_P']:.3g}, dphi {r['dphi']:.3g}, "
                  f"phi(P/E = 1) {r['phi_end']:.5f}", flush=True)
            with open(RESULTS / f"{a.output}.csv", "w", newline="") as fh:
                w = csv.DictWriter(fh, cols, extrasaction="ignore")
                w.writeheader()
                w.writerows(rows)
    total = time.perf_counter() - t_all
    plot(rows, RESULTS / f"{a.output}.png")
    p_ref = ref[0]
    lines = [f"# Single particle: run time against error (reference: {reference_comment()})", "",
             f"err φ = max relative error of φ_p at the reference's pressures with φ_p ≤ {PHI_COMPARE} "
             f"(P/E ≤ 0.16); err P = max relative error of P_p/E at equal φ_p there (interpolation in ln P); "
             f"|Δφ| = max absolute difference of φ_p at all the reference's pressures (P/E {p_ref.min():.3g} … "
             f"{p_ref.max():.3g}); φ(P/E = 1) = φ_p at the last stage (φ_p > 1: the quadratic edges bulge past "
             "the walls between the contact nodes). Run time = the study's compute stage (16 stages, P/E = 1e-3 … 1).", "",
             "| element | volumetric | elements | boundary segments (graded) | h | steps | run time (s) | err φ_p | "
             "err P_p/E | \\|Δφ\\| | φ(P/E = 1) | status |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in sorted(rows, key=lambda r: (r["element"], r["volumetric"], r["elements"], -r["h"])):
        lines.append(f"| {r['element']} | {r['volumetric']} | {r['elements']} | {r['boundary_segments']} | {r['h']:g} | "
                     f"{r['steps']} | {r['seconds']:.1f} | {100 * r['err_phi']:.2f} % | {100 * r['err_P']:.1f} % | "
                     f"{r['dphi']:.4f} | {r['phi_end']:.4f} | {r['status']} |")
    lines += ["", f"Whole benchmark: {total:.0f} s (`python benchmarks/single_particle_cost.py "
              f"--elements {' '.join(map(str, a.elements))} --types {' '.join(a.types)} --time-steps "
              f"{' '.join(f'{h:g}' for h in a.time_steps)}"
              + (f" --skip {' '.join(a.skip)}" if a.skip else "") + (f" --graded {' '.join(a.graded)}" if a.graded else "")
              + (f" --volumetric {' '.join(a.volumetric)}" if a.volumetric != ["standard"] else "")
              + (f" --output {a.output}" if a.output != "single_particle_cost" else "") + "`)."]
    (RESULTS / f"{a.output}.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
