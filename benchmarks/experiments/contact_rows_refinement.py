"""Which rigid–soft contact formulation is nearer a converged soft mesh: node rows alone or node
and segment rows (`solver.rigid_soft_rows`), under mesh refinement of the soft disks.

For each number of elements per soft disk and each formulation: the mixture study's pre stage
(the same jammed packing every time: N rigid disks, seed 1; a fraction κ made soft, T3 by
default) into WORKDIR/<element>x<elements>_<rows>/, its one run as a child process
(`mixture_scaling.run`), and per equilibrated stage φ (element areas), φ_contact (areas inside the
boundary-node polygons) and φ_net (φ_contact less the area rigid disks share with the soft
polygons), from post.table. The two formulations must meet as the mesh is refined (the segment
between two nodes approaches the circle), and the finest mesh is the reference for both.
Interrupted runs resume from their checkpoints when the benchmark is started again. Writes
benchmarks/results/contact_rows_refinement_<element>_mu<μ>.{md,json}.

    python benchmarks/experiments/contact_rows_refinement.py --workdir /tmp/rows --elements 92 368 1472
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

sys.path.append(str(Path(__file__).resolve().parents[1]))  # benchmarks/: the shared helpers
from mixture_scaling import describe, run  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
RESULTS = Path(__file__).resolve().parents[1] / "results"
ROWS = ("nodes", "nodes_and_segments")


def prepare(study: Path, a, elements: int, rows: str) -> tuple[Path, Path]:
    """The run's scene and output folder (the study's pre stage, once)."""
    if not (study / "study.json").is_file():
        subprocess.run([sys.executable, "-m", "studies.mixture_compaction.pre", "--workdir", str(study),
                        "--n", str(a.n), "--kappa", str(a.kappa), "--mu", str(a.mu), "--element", a.element,
                        "--elements", str(elements), "--pressures", *map(str, a.pressures),
                        "--set", f"solver.rigid_soft_rows={rows}"], cwd=ROOT, check=True, stdout=subprocess.DEVNULL)
    entry = json.loads((study / "study.json").read_text())["runs"][0]
    return study / entry["scene"], study / entry["out"]


def stage_measures(out: Path, mu: float) -> list[dict]:
    """φ, φ_contact, φ_net at the end of each equilibrated stage (post.table)."""
    from post import measures
    from post.table import measure_output

    rows = measure_output(out, measures.default_min_contacts(mu))
    return [{"P": float(r["pressure_applied"]), "phi": float(r["phi"]), "phi_contact": float(r["phi_contact"]),
             "phi_net": float(r["phi_net"])} for r in rows if r["equilibrated"]]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--workdir", required=True)
    ap.add_argument("--n", type=int, default=144)
    ap.add_argument("--kappa", type=float, default=0.5)
    ap.add_argument("--mu", type=float, default=0.2)
    ap.add_argument("--element", choices=("T3", "T6"), default="T3")
    ap.add_argument("--elements", type=int, nargs="+", default=[92, 368, 1472])
    ap.add_argument("--pressures", type=float, nargs="+", default=[0.01, 0.03, 0.1, 0.3, 1.0])
    ap.add_argument("--rows", nargs="+", choices=ROWS, default=list(ROWS), help="the formulations to run")
    a = ap.parse_args()
    sys.path.insert(0, str(ROOT))
    RESULTS.mkdir(exist_ok=True)
    stem = f"contact_rows_refinement_{a.element}_mu{a.mu:g}"
    record_file, table_file = RESULTS / f"{stem}.json", RESULTS / f"{stem}.md"
    record = json.loads(record_file.read_text()) if record_file.is_file() else {}
    for elements in a.elements:
        for rows in a.rows:
            key = f"{a.element}x{elements}_{rows}"
            scene, out = prepare(Path(a.workdir) / key, a, elements, rows)
            entry = record.setdefault(key, {"sessions": []})
            if not any((out / m).is_file() for m in ("COMPLETE", "INCOMPLETE", "FAILED")):
                entry["sessions"].append(run(scene, out, 10.0))
            entry.update(describe(out), elements=elements, rows=rows, stages_measured=stage_measures(out, a.mu),
                         seconds=sum(s["seconds"] for s in entry["sessions"]))
            record_file.write_text(json.dumps(record, indent=1) + "\n")
            print(f"{key}: {entry['status']}, {entry['steps']} steps, {entry['seconds']:.0f} s", flush=True)
            _markdown(record, a, table_file)


def _markdown(record: dict, a, path: Path) -> None:
    pressures = sorted({s["P"] for e in record.values() for s in e["stages_measured"]})
    head = " | ".join(f"P/E = {p:g}" for p in pressures)
    lines = [f"# Node rows against node and segment rows under refinement (N = {a.n}, κ = {a.kappa:g}, μ = {a.mu:g}, "
             f"{a.element})", "",
             f"`python benchmarks/experiments/contact_rows_refinement.py --workdir W --n {a.n} --kappa {a.kappa:g} --mu {a.mu:g} "
             f"--element {a.element} --elements " + " ".join(str(e) for e in sorted({e["elements"] for e in record.values()}))
             + "`: one jammed packing, "
             "the soft disks meshed with each number of elements, each run with `solver.rigid_soft_rows = \"nodes\"` "
             "and `\"nodes_and_segments\"`; one thread per run.", "",
             "Equilibrated φ (element areas) per stage, then φ_net (boundary polygons less rigid overlap):", "",
             f"| mesh | rows | status | steps | Newton its | s | {head} |",
             "|---|---|---|---|---|---|" + "---|" * len(pressures)]
    for e in sorted(record.values(), key=lambda e: (e["elements"], e["rows"])):
        by_p = {s["P"]: s for s in e["stages_measured"]}
        cells = " | ".join(f"{by_p[p]['phi']:.4f} / {by_p[p]['phi_net']:.4f}" if p in by_p else "–" for p in pressures)
        lines.append(f"| {a.element} × {e['elements']} | {e['rows']} | {e['status']} | {e['steps']} | "
                     f"{e['newton_iterations']} | {e['seconds']:.0f} | {cells} |")
    path.write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
