"""Newton iterations of the single particle against the depth of Anderson acceleration.

The single-particle study's default scene (16 stages to P/E = 1, h = 10), run once per
depth of ``compute.stepping.newton.ANDERSON`` in this process: steps, Newton iterations, step
cuts, compute wall time and the final φ_p. Writes benchmarks/results/anderson_depth.md.

    python benchmarks/anderson_depth.py [--depths 4 6 8 12]
"""

from __future__ import annotations

import argparse
import io
import tempfile
import time
from pathlib import Path

import compute.stepping.newton as newton
from compute.progress import Display
from compute.run import Run
from pre.single_particle import ELEMENTS, write

RESULTS = Path(__file__).resolve().parent / "results"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--depths", type=int, nargs="+", default=[4, 6, 8, 12])
    a = ap.parse_args()
    lines = ["# Single particle: Newton iterations against the Anderson depth", "",
             f"`python benchmarks/anderson_depth.py --depths {' '.join(map(str, a.depths))}` (T6 standard, target {ELEMENTS} triangles, 16 stages "
             "to P/E = 1, h = 10; the first depth also pays numba's cache loading).", "",
             "| depth | steps | Newton iterations | cuts | compute (s) | final φ_p |", "|---|---|---|---|---|---|"]
    with tempfile.TemporaryDirectory() as tmp:
        write(Path(tmp) / "scene")
        for depth in a.depths:
            newton.ANDERSON = depth
            t0 = time.perf_counter()
            run = Run(Path(tmp) / "scene", Path(tmp) / f"out{depth}", log=lambda m: None,
                      display=Display(1, stream=io.StringIO()))
            state = run.execute()
            s = run.stepper.stats
            lines.append(f"| {depth} | {state.step} | {s['newton_iterations']} | {s['cuts']} | "
                         f"{time.perf_counter() - t0:.1f} | {run.model.phi(state.q):.6f} |")
            print(lines[-1], flush=True)
    (RESULTS / "anderson_depth.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
