"""Jamming of N polydisperse rigid disks (the paper's preparation), frictionless and frictional:
φ₀, Z₀ (all particles, and without rattlers), the stress check and the cost.

    python benchmarks/jamming_rigid.py [--n 1500] [--mu 0 0.2] [--workdir DIR]

Writes benchmarks/results/jamming_rigid_N<n>.md (keeps the runs in --workdir when given).
"""

import argparse
import tempfile
import time
from pathlib import Path

from post.table import measure_output
from pre.jamming import jammed_rigid_scene


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--n", type=int, default=1500)
    p.add_argument("--mu", type=float, nargs="+", default=[0.0, 0.2])
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--workdir", default=None)
    a = p.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(a.workdir or tmp)
        for mu in a.mu:
            w = base / f"n{a.n}_mu{mu:g}"
            t0 = time.perf_counter()
            jammed_rigid_scene(w, a.n, mu, a.seed, [1.0], log=lambda m: None)
            elapsed = time.perf_counter() - t0
            last = measure_output(w / "jamming" / "out", min_contacts=3 if mu == 0 else 2)[-1]
            steps = sum(1 for _ in open(w / "jamming" / "out" / "history.csv")) - 1
            rows.append((mu, last, steps, elapsed))
            print(mu, {k: last[k] for k in ("phi", "Z", "Z_no_rattlers", "Z_constraints", "n_rattlers", "P", "P_walls")},
                  steps, f"{elapsed:.0f} s", flush=True)
    lines = [f"# Jamming of {a.n} polydisperse rigid disks (d in [0.8, 1.2]<d>, seed {a.seed}, P = 1, "
             "wall damping I* = 1e-3, h = 0.02, θ = 1, NLGS tol 1e-6)", "",
             "| μ | φ₀ | Z | Z no rattlers | Z_constraints (isostatic μ=0: 4 + 4/N) | rattlers | P/P_walls − 1 "
             "| steps | wall time (s) |",
             "|---|---|---|---|---|---|---|---|---|"]
    for mu, m, steps, el in rows:
        lines.append(f"| {mu:g} | {m['phi']:.4f} | {m['Z']:.3f} | {m['Z_no_rattlers']:.3f} | "
                     f"{m['Z_constraints']:.3f} | {m['n_rattlers']} | "
                     f"{m['P'] / m['P_walls'] - 1:.1e} | {steps} | {el:.0f} |")
    out = Path(__file__).parent / "results" / f"jamming_rigid_N{a.n}.md"
    out.parent.mkdir(exist_ok=True)
    out.write_text("\n".join(lines) + "\n")
    print(out.read_text())


if __name__ == "__main__":
    main()
