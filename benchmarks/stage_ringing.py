"""How the walls ring in each pressure stage of a run, read from its history and log.

Per stage of each run folder: the box area A(t) against its value at the stage's end, its
turning points (A's differences changing sign, the excursion above 1e-4 of A), the mean time
between the first four of them (a half period of the breathing mode), the apparent damping
ratio from the logarithmic decrement of successive excursions on either side (the first three
pairs: δ = -ln(mean ratio), ζ = δ / √(π² + δ²)), the stage's least wall coefficient c from
``compute.log``, the bulk modulus K that c was computed from (c = ζ_set 2 √(4 K m), m = m_w + M/6
of compute.bodies.walls, M = φ A ρ at the stage's end) and the modulus the ringing implies,
4 K = m ω², ω = π / half period / √(1 - ζ²). Counts and times of the simulation, not of the
machine.

    python benchmarks/stage_ringing.py W/runs/*

A stage that did not ring (fewer than two turning points, or no excursion followed by one on
the other side) shows dashes.
"""

from __future__ import annotations

import argparse
import re
import sys
import tomllib
from pathlib import Path

import numpy as np

sys.path.append(str(Path(__file__).resolve().parent))
from stage_steps import read_history  # noqa: E402

SIGNIFICANT = 1e-4  # excursions below this fraction of A are not turning points


def ringing(t: np.ndarray, area: np.ndarray) -> tuple[float, float] | None:
    """(half period, apparent damping ratio) of the stage's areas ``area`` (n,) at times ``t`` (n,)
    around the last one, or None if it did not ring (module docstring)."""
    x = area - area[-1]
    d = np.diff(x)
    turns = [i for i in range(1, d.size) if d[i - 1] * d[i] < 0.0 and abs(x[i]) > SIGNIFICANT * area[-1]]
    if len(turns) < 2:
        return None
    half = float(np.mean(np.diff(t[turns[:4]])))
    ratios = [abs(x[b] / x[a]) for a, b in zip(turns[:3], turns[1:4]) if x[a] * x[b] < 0.0]
    if not ratios:
        return None
    delta = -np.log(np.mean(ratios))
    return half, float(delta / np.sqrt(np.pi**2 + delta**2))


def stage_table(run: Path) -> list[str]:
    """Markdown rows of ``run``'s stages (module docstring)."""
    h = read_history(run)
    log = (run / "out" / "compute.log").read_text()
    damping = {int(s): float(c) for s, c in re.findall(r"stage (\d+): wall damping at least ([\d.e+-]+)", log)}
    scene = tomllib.loads((run / "scene" / "scene.toml").read_text())
    densities = {m["density"] for m in scene["materials"].values()}
    if len(densities) != 1:
        raise ValueError(f"{run}: materials of different densities; the mode's mass needs one")
    rho, wall_mass, zeta_set = densities.pop(), scene["walls"]["mass"], scene["walls"]["damping_ratio"]
    rows = []
    for s in np.unique(h["stage"]).astype(int):
        r = h[h["stage"] == s]
        area = (r["xmax"] - r["xmin"]) * (r["ymax"] - r["ymin"])
        m = wall_mass + r["phi"][-1] * area[-1] * rho / 6.0
        c = damping.get(s)
        k_used = (c / (2.0 * zeta_set)) ** 2 / (4.0 * m) if c and zeta_set else None
        half, zeta, k_ring = "–", "–", "–"
        ring = ringing(r["time"], area)
        if ring is not None:
            omega = np.pi / ring[0] / np.sqrt(max(1.0 - ring[1] ** 2, 1e-12))
            half, zeta, k_ring = f"{ring[0]:.3g}", f"{ring[1]:.2f}", f"{m * omega**2 / 4.0:.3g}"
        cells = [run.name, s, r.size, half, zeta, c or "–", f"{k_used:.3g}" if k_used else "–", k_ring]
        rows.append("| " + " | ".join(str(x) for x in cells) + " |")
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", nargs="+", type=Path, help="run folders (scene/ and out/)")
    a = ap.parse_args()
    print("| run | stage | steps | half period | apparent ζ | c | K of c | K of the ringing |")
    print("|---|---|---|---|---|---|---|---|")
    for run in a.runs:
        print("\n".join(stage_table(run)))


if __name__ == "__main__":
    main()
