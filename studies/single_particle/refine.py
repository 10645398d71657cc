"""Single-particle study: mesh refinement (T3 and T6) and the regression data of the test suite.

Three series of levels: uniform T3 and uniform T6 (about 30 to 3000 similar triangles), and
boundary-graded T6 ("T6g": the interior of the 1000-element mesh, the boundary split into 240,
480, 960 segments, sizes growing inward; pre.mesh.reference_disk_mesh), run over the first 12
of the 16 stages (P/E <= 0.16, phi_p <= 0.95) with h = 2. The graded series
resolves the contact zones, whose half-width at P/E = 1e-3 (about 0.04 R) is below the element
size of every uniform mesh here. For every level it runs pre.py, compute.py and post.py in
WORKDIR/<level>/, then writes in WORKDIR:

- refinement.csv: series, elements, boundary_segments, P/E, phi_p for every equilibrated stage;
- refinement_differences.csv: for consecutive levels of one series, the largest relative
  difference of phi_p (at equal P) and of P_p/E (at equal phi_p, interpolated in log P) over
  the stages with phi_p <= 0.95;
- refinement_fits.csv: Eq. 2 (b, phi_p,max, fitted phi range) per level, with its element
  count, steps and run time;
- refinement.png: all the curves (paper Fig. 5).

With --data DIR it also writes DIR/reference_T6g.csv (the finest graded T6 curve) and
DIR/default_T6.csv (the default mesh, pre.single_particle.ELEMENTS), the regression data of
tests/deformable/test_single_particle_regression.py.

    python -m studies.single_particle.refine --workdir /tmp/sp_refine [--jobs 2] [--levels T6g:1000:960,...]
"""

from __future__ import annotations

if not __package__:  # run as a file (python studies/X/stage.py): studies/entry.py
    import pathlib, sys; sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2]))
    from studies.entry import run_as_file; run_as_file(__file__)

import argparse
import csv
import json
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from compute.progress import read_progress
from compute.scene import SCENE_FILE, read_parameters
from post.single_particle import curve_errors, element_count, soft_material, write_curve
from post.table import read_measures
from pre.single_particle import ELEMENTS

ROOT = Path(__file__).resolve().parents[2]

# series -> levels (target elements, boundary segments or None for a uniform mesh)
SERIES = {"T3": [(n, None) for n in (30, 92, 300, 1000, 3000)],
          "T6": [(n, None) for n in (30, 92, ELEMENTS, 300, 1000, 3000)],  # ELEMENTS: the default disk
          "T6g": [(1000, b) for b in (240, 480, 960)]}
PHI_COMPARE = 0.95
# The graded levels stop at the 12th of the default 16 stages (P/E = 10^-0.8 = 0.16, phi_p ~ 0.95,
# the end of the convergence criterion's range): beyond it the flats hold hundreds of contact
# nodes and a step of the 8700-element level costs minutes.
GRADED_STAGES = 12
# ... and take h = 2 instead of 10: with hundreds of contact nodes on one body the NLGS sweeps per
# step grow like h^2 (README, quasi-static settings) and dominate; at h = 10 the 960-segment
# level needed 10^4-4x10^4 sweeps per step and stalled at P/E = 0.016.
GRADED_TIME_STEP = 2.0


def level_name(series: str, n: int, segments: int | None) -> str:
    return f"{series}_{n}" if segments is None else f"{series}_{n}_b{segments}"


def run_level(work: Path, series: str, n: int, segments: int | None, graded_stages: int = GRADED_STAGES,
              volumetric: str | None = None) -> Path:
    """pre, compute and post of one level in WORKDIR/<level>/, each a process (run in parallel);
    a graded level runs the first ``graded_stages`` of the 16 stages; ``volumetric`` is pre's
    --volumetric (None: its default)."""
    d = work / level_name(series, n, segments)

    def stage(name: str, *args: str, **kw) -> None:
        subprocess.run([sys.executable, "-m", f"studies.single_particle.{name}", "--workdir", str(d), *args],
                       cwd=ROOT, check=True, **kw)

    if not (d / "out" / "COMPLETE").is_file() and not (d / "out" / "post" / "fit.json").is_file():
        p_max = float(np.geomspace(1e-3, 1.0, 16)[graded_stages - 1])
        extra = [] if segments is None else ["--boundary-segments", str(segments), "--p-max", repr(p_max),
                                             "--stages", str(graded_stages), "--time-step", repr(GRADED_TIME_STEP)]
        extra += ["--volumetric", volumetric] if volumetric and series != "T3" else []
        stage("pre", "--element-type", series[:2], "--elements", str(n), *extra, stdout=subprocess.DEVNULL)
        with open(d / "compute.log", "w") as log:
            stage("compute", stdout=log, stderr=subprocess.STDOUT)
    stage("post", stdout=subprocess.DEVNULL)
    return d


def read_curve(d: Path) -> tuple[np.ndarray, np.ndarray]:
    """(P_walls/E, φ_p) of the level's equilibrated stages (its out/post/measures.csv)."""
    m = read_measures(d / "out" / "post" / "measures.csv")
    eq = m["equilibrated"].astype(bool)
    return m["P_walls"][eq], m["phi"][eq]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--workdir", required=True)
    ap.add_argument("--jobs", type=int, default=1, help="levels run in parallel (processes)")
    ap.add_argument("--levels", default=None,
                    help="comma-separated SERIES:N[:SEGMENTS] list, e.g. T6:92,T6g:1000:480 (default: all levels)")
    ap.add_argument("--graded-stages", type=int, default=GRADED_STAGES,
                    help=f"stages of the graded levels, of the default 16 (default {GRADED_STAGES}: P/E <= 0.16)")
    ap.add_argument("--volumetric", choices=("standard", "mean_dilatation"), default=None,
                    help="volumetric term of the T6 levels (default: pre's, standard)")
    ap.add_argument("--data", default=None, help="write the finest graded and the default T6 curves in this folder")
    a = ap.parse_args(argv)
    work = Path(a.workdir)
    work.mkdir(parents=True, exist_ok=True)
    if a.levels:
        levels = []
        for item in a.levels.split(","):
            parts = item.split(":")
            if parts[0] not in SERIES or len(parts) not in (2, 3):
                ap.error(f"--levels {item!r}: expected SERIES:N[:SEGMENTS] with SERIES in {sorted(SERIES)}")
            levels.append((parts[0], int(parts[1]), int(parts[2]) if len(parts) == 3 else None))
    else:
        levels = [(e, n, b) for e, ls in SERIES.items() for n, b in ls]
    # the costliest levels first, so that parallel jobs end together
    by_cost = sorted(levels, key=lambda lv: (lv[2] or 0, lv[1] * (4 if lv[0] != "T3" else 1)), reverse=True)
    with ThreadPoolExecutor(a.jobs) as pool:
        done = dict(zip(by_cost, pool.map(lambda lv: run_level(work, *lv, a.graded_stages, a.volumetric), by_cost)))
    dirs = {lv: done[lv] for lv in levels}
    curves = {k: read_curve(d) for k, d in dirs.items()}
    counts = {k: element_count(d / "scene") for k, d in dirs.items()}
    with open(work / "refinement.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["series", "elements", "boundary_segments", "P_over_E", "phi_p"])
        for (e, n, b), (p, f) in curves.items():
            for pi, fi in zip(p, f):
                w.writerow([e, counts[(e, n, b)], b or "", repr(float(pi)), repr(float(fi))])
    with open(work / "refinement_differences.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["series", "coarse", "fine", "max_rel_diff_phi", "max_rel_diff_P_at_equal_phi"])
        for e in SERIES:
            ls = sorted((k for k in curves if k[0] == e), key=counts.get)
            for k0, k1 in zip(ls, ls[1:]):
                dphi, dp = curve_errors(*curves[k0], *curves[k1], PHI_COMPARE)
                w.writerow([e, counts[k0], counts[k1], f"{dphi:.3g}", f"{dp:.3g}"])
    with open(work / "refinement_fits.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["element", "elements", "boundary_segments", "b", "phi_p_max", "phi_min", "phi_max", "n_points",
                    "steps", "seconds"])
        for (e, n, b), d in dirs.items():
            fit = json.loads((d / "out" / "post" / "fit.json").read_text())
            progress = read_progress(d / "out") or {}
            steps, secs = progress.get("step", ""), f"{progress['elapsed']:.1f}" if "elapsed" in progress else ""
            w.writerow([e[:2], counts[(e, n, b)], b or "", f"{fit['b']:.4f}", f"{fit['phi_p_max']:.4f}",
                        f"{fit['phi_range'][0]:.4f}", f"{fit['phi_range'][1]:.4f}", fit["n_points"], steps, secs])
    from post.plots import new_figure, save_figure

    fig, axes = new_figure(1, len(SERIES), size=(5.0, 4.0))
    for e, ax in zip(SERIES, axes[0]):
        for k, (p, f) in sorted(curves.items(), key=lambda kv: counts[kv[0]]):
            if k[0] == e:
                ax.plot(p, f, "o-", ms=2.5, label=f"{e}, {counts[k]} el." + (f", {k[2]} boundary seg." if k[2] else ""))
        ax.set_xscale("log")
        ax.set_xlabel(r"$P_p/E$")
        ax.set_ylabel(r"$\phi_p$")
        ax.legend(fontsize=7)
    save_figure(fig, work / "refinement.png")
    if a.data:
        graded = [k for k in curves if k[0] == "T6g"]
        for k, name in ((max(graded, key=counts.get) if graded else None, "reference_T6g.csv"),
                        (("T6", ELEMENTS, None), "default_T6.csv")):
            if k in curves:
                settings = (f"pre settings of the graded series: {a.graded_stages} stages, h = {GRADED_TIME_STEP:g}"
                            if k[2] else "default pre settings")
                if read_parameters(dirs[k] / "scene" / SCENE_FILE)["solver"].hold_rotation:
                    settings += ", rigid rotation held"
                write_curve(Path(a.data) / name, *curves[k],
                            f"single-particle curve, T6 {soft_material(dirs[k] / 'scene').volumetric.replace('_', ' ')}, "
                            f"{counts[k]} elements"
                            + (f" graded to {k[2]} boundary segments" if k[2] else "")
                            + f", equilibrated stages (python -m studies.single_particle.refine, {settings})")
    print((work / "refinement_differences.csv").read_text())
    print((work / "refinement_fits.csv").read_text())
    return 0


if __name__ == "__main__":
    sys.exit(main())
