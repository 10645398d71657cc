"""The walls' damping ratio (walls.damping_ratio) on a pressed soft disk: steps and overshoot.

One T3 disk (40 elements) between four pressure-driven walls, P/E = 1e-3, 1e-2, 3e-2, h = 0.1
(small enough for the disk to ring), θ = 1, a light damping of the inertial-number kind
(I* = 0.5) that the ratio's coefficient replaces wherever it is larger. For each ratio ζ:
the steps of the two stages whose damping has a secant modulus (the first has none), how far
φ passed the stage's end value (the overshoot) and the end φ. Critical damping is the least
with no overshoot, which is what the ratio's estimate of the mode is checked against.

    python benchmarks/wall_damping.py --ratios 0 0.25 0.5 0.7 1 1.5 2 --output wall_damping_disk

writes benchmarks/results/OUTPUT.md (or prints the table without --output).
"""

from __future__ import annotations

import argparse
import csv
import tempfile
from pathlib import Path

import numpy as np

from compute.run import run
from pre import single_particle
from pre.scene import copy_scene

RESULTS = Path(__file__).resolve().parent / "results"
PRESSURES = [1e-3, 1e-2, 3e-2]


def disk_stages(folder: Path, ratio: float) -> dict:
    """Run the pressed disk with damping ratio ``ratio`` in ``folder``; per stage (3,) its
    steps, overshoot (largest φ minus the end φ) and end φ."""
    single_particle.write(folder / "base", element="T3", elements=40, pressures=PRESSURES, time_step=0.1,
                          check_every=20)
    scene = copy_scene(folder / "base", folder / "scene",
                       {"walls.damping_ratio": ratio, "walls.damping_inertial_number": 0.5})
    run(scene, folder / "out", log=lambda m: None)
    rows = list(csv.DictReader(open(folder / "out" / "history.csv")))
    stage = np.array([int(r["stage"]) for r in rows])
    phi = np.array([float(r["phi"]) for r in rows])
    parts = [phi[stage == s] for s in range(len(PRESSURES))]
    return {"steps": [len(p) for p in parts], "overshoot": [float(p.max() - p[-1]) for p in parts],
            "phi": [float(p[-1]) for p in parts]}


def table(ratios) -> str:
    lines = ["| ζ | steps per stage | overshoot of φ, stages 2 and 3 | end φ per stage |", "|---|---|---|---|"]
    with tempfile.TemporaryDirectory() as tmp:
        for ratio in ratios:
            r = disk_stages(Path(tmp) / str(ratio), ratio)
            lines.append(f"| {ratio:g} | {' '.join(map(str, r['steps']))} | "
                         f"{' '.join(f'{o:.2e}' for o in r['overshoot'][1:])} | "
                         f"{' '.join(f'{p:.6f}' for p in r['phi'])} |")
    return "\n".join(lines)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ratios", type=float, nargs="+", default=[0.0, 0.25, 0.5, 0.7, 1.0, 1.5, 2.0])
    parser.add_argument("--output", help="write benchmarks/results/OUTPUT.md")
    args = parser.parse_args(argv)
    text = table(args.ratios)
    if args.output:
        (RESULTS / f"{args.output}.md").write_text(text + "\n")
    print(text)


if __name__ == "__main__":
    main()
