"""Where an extrapolating stage-end test would end the stages of a run already made.

Replays a run's history.csv: in each stage, once its load is fully applied, φ at steps n − 2g,
n − g and n (g = --gap) give Aitken's Δ² estimate of the stage's end φ,
φ∞ ≈ φ_n − (φ_n − φ_{n−g})² / ((φ_n − φ_{n−g}) − (φ_{n−g} − φ_{n−2g})), taken only on a
monotone, converging approach (ratio of the two differences in [0, 0.9)). The test ends the
stage at the first step where |φ∞ − φ_n| < --tolerance φ_n. Printed per stage: that step and the
stage's own length, φ∞, the run's own end φ and, with --reference (a tight run's history.csv),
the difference from that run's stage end. Nothing is run: the history is the trajectory the
test would have seen up to its end.

    python benchmarks/experiments/stage_end_extrapolation.py OUT/history.csv --tolerance 3e-5 \\
        --reference TIGHT_OUT/history.csv
"""

from __future__ import annotations

import argparse
import csv

import numpy as np


def stage_histories(path) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """{stage: (φ (n,), applied pressure (n,))} of a history.csv."""
    phi: dict[int, list] = {}
    pressure: dict[int, list] = {}
    for row in csv.DictReader(open(path)):
        s = int(row["stage"])
        phi.setdefault(s, []).append(float(row["phi"]))
        pressure.setdefault(s, []).append(float(row["pressure_applied"]))
    return {s: (np.array(phi[s]), np.array(pressure[s])) for s in phi}


def extrapolated_end(phi: np.ndarray, pressure: np.ndarray, tolerance: float, gap: int) -> tuple[int, float] | None:
    """(step index, φ∞) where the Aitken test first passes in one stage (φ, pressure (n,)), or None."""
    start = int(np.argmax(pressure >= pressure.max() * (1 - 1e-12)))  # the load fully applied
    for n in range(start + 2 * gap, len(phi)):
        d1, d2 = phi[n - gap] - phi[n - 2 * gap], phi[n] - phi[n - gap]
        if d1 == 0.0 or d2 == d1 or not 0.0 <= d2 / d1 < 0.9:
            continue
        estimate = phi[n] - d2 * d2 / (d2 - d1)
        if abs(estimate - phi[n]) < tolerance * phi[n]:
            return n, estimate
    return None


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("history")
    ap.add_argument("--tolerance", type=float, default=1e-4)
    ap.add_argument("--gap", type=int, default=20)
    ap.add_argument("--reference", help="a tight run's history.csv (its stage ends)")
    a = ap.parse_args()
    reference = {s: p[-1] for s, (p, _) in stage_histories(a.reference).items()} if a.reference else {}
    for s, (phi, pressure) in sorted(stage_histories(a.history).items()):
        end = extrapolated_end(phi, pressure, a.tolerance, a.gap)
        if end is None:
            print(f"stage {s}: no end within its {len(phi)} steps; its end φ {phi[-1]:.5f}")
            continue
        n, estimate = end
        against = f"; φ∞ − reference {estimate - reference[s]:+.1e}" if s in reference else ""
        print(f"stage {s}: ends at step {n + 1} of {len(phi)}; φ∞ {estimate:.5f}, its end φ {phi[-1]:.5f}{against}")


if __name__ == "__main__":
    main()
