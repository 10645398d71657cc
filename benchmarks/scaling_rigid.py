"""Cost of a rigid NSCD step against N: time per step, NLGS sweeps per step, time per sweep.

For each N a frictional packing (μ = 0.2) is jammed by the pre stage's compression (the same
settings as the rigid jamming study); the measures are then taken over steps of the jammed
packing under pressure (warm-started NLGS, tolerance 1e-6), all in one process, one after the
other. Writes benchmarks/results/scaling_rigid.md.

    python benchmarks/scaling_rigid.py [--sizes 100 400 1500 6000] [--steps 200]
"""

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from compute.model import Model
from compute.scene import read_scene
from compute.stepping.moreau_jean import Stepper
from pre.jamming import jammed_rigid_scene


def measure(n: int, steps: int, workdir: Path) -> dict:
    t0 = time.perf_counter()
    scene = jammed_rigid_scene(workdir / f"n{n}", n, 0.2, 1, [1.0], overrides={"solver.time_step": 0.1})
    prep = time.perf_counter() - t0
    model = Model(read_scene(scene))
    stepper = Stepper(model)
    state = model.initial_state()
    state, _ = stepper.step(state, 1.0)  # compile / detect outside the timing
    sweeps, contacts = [], []
    t0 = time.perf_counter()
    for _ in range(steps):
        state, rep = stepper.step(state, 1.0)
        sweeps.append(rep.sweeps)
        contacts.append(len(rep.contacts))
    dt = (time.perf_counter() - t0) / steps
    s, c = float(np.mean(sweeps)), float(np.mean(contacts))
    return dict(n=n, prep_s=prep, step_ms=1e3 * dt, sweeps=s, candidates=c,
                ns_per_contact_sweep=1e9 * dt / (s * c))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--sizes", type=int, nargs="+", default=[100, 400, 1500, 6000])
    p.add_argument("--steps", type=int, default=200)
    a = p.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for n in a.sizes:
            rows.append(measure(n, a.steps, Path(tmp)))
            print(rows[-1], flush=True)
    lines = ["# Rigid NSCD step cost against N (μ = 0.2, jammed, P = 1, h = 0.1, NLGS tol 1e-6)", "",
             "| N | preparation (s) | ms / step | sweeps / step | candidates | ns / (contact·sweep) |",
             "|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['n']} | {r['prep_s']:.1f} | {r['step_ms']:.2f} | {r['sweeps']:.0f} | "
                     f"{r['candidates']:.0f} | {r['ns_per_contact_sweep']:.1f} |")
    out = Path(__file__).parent / "results" / "scaling_rigid.md"
    out.parent.mkdir(exist_ok=True)
    out.write_text("\n".join(lines) + "\n")
    print(out.read_text())


if __name__ == "__main__":
    main()
