"""Single-particle study: mesh refinement (T3 and T6) and the regression data of the test suite.

For every (element type, target element count) runs pre.py, compute.py and post.py in
WORKDIR/<element>_<n>/, then writes in WORKDIR:

- refinement.csv: element, elements, pressure (P/E), phi_p for every equilibrated stage;
- refinement_differences.csv: for consecutive levels of one element type, the largest
  relative difference of phi_p and of P_p/E (P/E at equal phi_p, interpolated in log P)
  over the stages with phi_p <= 0.95;
- refinement_fits.csv: Eq. 2 (b, phi_p,max, fitted phi range) per level;
- refinement.png: all the curves (paper Fig. 5).

With --data DIR it also writes DIR/reference_T6_<n>.csv (the finest T6 curve) and
DIR/default_T6_92.csv (the default mesh), the regression data of
tests/deformable/test_single_particle_regression.py.

    python studies/single_particle/refine.py --workdir /tmp/sp_refine [--jobs 2]
"""

from __future__ import annotations

import argparse
import csv
import json
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != HERE]

LEVELS = {"T3": (30, 92, 300, 1000, 3000), "T6": (30, 92, 300, 1000, 3000)}
PHI_COMPARE = 0.95


def run_level(work: Path, element: str, n: int, extra: list[str]) -> Path:
    d = work / f"{element}_{n}"
    if not (d / "out" / "COMPLETE").is_file() and not (d / "out" / "post" / "fit.json").is_file():
        py = sys.executable
        subprocess.run([py, str(HERE / "pre.py"), "--workdir", str(d), "--element-type", element,
                        "--elements", str(n), *extra], check=True, stdout=subprocess.DEVNULL)
        with open(d / "compute.log", "w") as log:
            subprocess.run([py, str(HERE / "compute.py"), "--workdir", str(d)], check=True, stdout=log,
                           stderr=subprocess.STDOUT)
    subprocess.run([sys.executable, str(HERE / "post.py"), "--workdir", str(d)], check=True,
                   stdout=subprocess.DEVNULL)
    return d


def read_curve(d: Path) -> tuple[np.ndarray, np.ndarray]:
    rows = [r for r in csv.DictReader(open(d / "out" / "post" / "measures.csv")) if r["equilibrated"] == "1"]
    return np.array([float(r["P_walls"]) for r in rows]), np.array([float(r["phi"]) for r in rows])


def differences(coarse, fine) -> tuple[float, float]:
    """Largest relative differences of phi at equal P and of P at equal phi (phi <= PHI_COMPARE)."""
    (pc, fc), (pf, ff) = coarse, fine
    sel = (fc <= PHI_COMPARE) & (ff <= PHI_COMPARE)
    dphi = float(np.max(np.abs(fc[sel] / ff[sel] - 1))) if sel.any() else np.nan
    # P at equal phi: interpolate log P of the fine curve at the coarse phi values (monotone part)
    ok = (fc <= PHI_COMPARE) & (fc >= ff.min()) & (fc <= ff.max())
    order = np.argsort(ff)
    p_fine = np.exp(np.interp(fc[ok], ff[order], np.log(pf[order])))
    dp = float(np.max(np.abs(pc[ok] / p_fine - 1))) if ok.any() else np.nan
    return dphi, dp


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--workdir", required=True)
    ap.add_argument("--jobs", type=int, default=1, help="levels run in parallel (processes)")
    ap.add_argument("--elements", default=None, help="comma-separated T3:N,T6:N list (default: all levels)")
    ap.add_argument("--data", default=None, help="write the finest and the default T6 curves in this folder")
    a = ap.parse_args(argv)
    work = Path(a.workdir)
    work.mkdir(parents=True, exist_ok=True)
    levels = ([(e, int(n)) for e, n in (x.split(":") for x in a.elements.split(","))] if a.elements
              else [(e, n) for e, ns in LEVELS.items() for n in ns])
    with ThreadPoolExecutor(a.jobs) as pool:
        dirs = dict(zip(levels, pool.map(lambda en: run_level(work, en[0], en[1], []), levels)))
    curves = {k: read_curve(d) for k, d in dirs.items()}
    with open(work / "refinement.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["element", "elements", "P_over_E", "phi_p"])
        for (e, n), (p, f) in curves.items():
            for pi, fi in zip(p, f):
                w.writerow([e, n, repr(float(pi)), repr(float(fi))])
    with open(work / "refinement_differences.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["element", "coarse", "fine", "max_rel_diff_phi", "max_rel_diff_P_at_equal_phi"])
        for e in LEVELS:
            ns = sorted(n for ee, n in curves if ee == e)
            for n0, n1 in zip(ns, ns[1:]):
                dphi, dp = differences(curves[(e, n0)], curves[(e, n1)])
                w.writerow([e, n0, n1, f"{dphi:.3g}", f"{dp:.3g}"])
    with open(work / "refinement_fits.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["element", "elements", "b", "phi_p_max", "phi_min", "phi_max", "n_points", "steps", "seconds"])
        for (e, n), d in dirs.items():
            fit = json.loads((d / "out" / "post" / "fit.json").read_text())
            log = (d / "compute.log").read_text().strip().splitlines()[-1] if (d / "compute.log").is_file() else ""
            parts = log.split()
            steps, secs = (parts[0], parts[3]) if len(parts) > 3 and parts[1] == "steps" else ("", "")
            w.writerow([e, n, f"{fit['b']:.4f}", f"{fit['phi_p_max']:.4f}", f"{fit['phi_range'][0]:.4f}",
                        f"{fit['phi_range'][1]:.4f}", fit["n_points"], steps, secs])
    from post.plots import new_figure, save_figure

    fig, axes = new_figure(1, 2, size=(5.0, 4.0))
    for k, (e, ax) in enumerate(zip(LEVELS, axes[0])):
        for (ee, n), (p, f) in sorted(curves.items()):
            if ee == e:
                ax.plot(p, f, "o-", ms=2.5, label=f"{e}, {n} el.")
        ax.set_xscale("log")
        ax.set_xlabel(r"$P_p/E$")
        ax.set_ylabel(r"$\phi_p$")
        ax.legend(fontsize=7)
    save_figure(fig, work / "refinement.png")
    if a.data:
        data = Path(a.data)
        data.mkdir(parents=True, exist_ok=True)
        finest = max(n for e, n in curves if e == "T6")
        for n, name in ((finest, f"reference_T6_{finest}.csv"), (92, "default_T6_92.csv")):
            if ("T6", n) not in curves:
                continue
            p, f = curves[("T6", n)]
            with open(data / name, "w", newline="") as fh:
                fh.write(f"# single-particle curve, T6 mean dilatation, {n} target elements, equilibrated "
                         f"stages (studies/single_particle/refine.py, default pre.py settings)\n")
                w = csv.writer(fh)
                w.writerow(["P_over_E", "phi_p"])
                for pi, fi in zip(p, f):
                    w.writerow([repr(float(pi)), repr(float(fi))])
    print((work / "refinement_differences.csv").read_text())
    print((work / "refinement_fits.csv").read_text())
    return 0


if __name__ == "__main__":
    sys.exit(main())
