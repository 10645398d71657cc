"""How far a step's linearised segment-disk gaps are from the gaps after the step.

The rows of a step are made at q_n; the contact solve asks g + h u_n >= 0 of the predicted
end-of-step gap. The node-disk gap |x_d - x_g| - r is convex in the positions, so the real gap
after the step is never below the prediction; the segment-disk gap (the disk against a segment's
line) is not, and a segment that turns by an angle a within the step brings the disk closer
than predicted by about r a² / 2. For each of --steps steps from a run's checkpoint this prints
the segment-disk rows that end the step more than --depth inside, the largest turn of a segment
near a contact, and, for the first of those rows, (after - predicted) against -r a² / 2 (not for
a step taken in sub-steps: each has its own rows).

    python benchmarks/experiments/segment_gap_linearisation.py --scene SCENE --run OUT --pressure 0.1 --steps 4 [--contact-tolerance 1e-6]

SCENE must have solver.rigid_soft_rows = "nodes_and_segments"; OUT is a copy of its output
folder with a checkpoint (it is copied again to a temporary folder, so OUT is not changed).
"""

from __future__ import annotations

import argparse
import dataclasses
import shutil
import tempfile
from pathlib import Path

import numpy as np


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", type=Path, required=True)
    ap.add_argument("--run", type=Path, required=True, help="output folder with a checkpoint")
    ap.add_argument("--pressure", type=float, required=True, help="the stage's pressure")
    ap.add_argument("--steps", type=int, default=4)
    ap.add_argument("--depth", type=float, default=5e-4)
    ap.add_argument("--contact-tolerance", type=float, help="the contact solvers' tolerance instead of the scene's")
    args = ap.parse_args()

    from compute import solvers
    from compute.contact import detection
    from compute.run import Run

    out = Path(tempfile.mkdtemp()) / "out"
    shutil.copytree(args.run, out)
    run = Run(args.scene, out, resume=True, log=lambda m: None)
    m, st = run.model, run.state
    if args.contact_tolerance:
        run.stepper.solver = solvers.for_model(dataclasses.replace(m.scene.solver, contact_tolerance=args.contact_tolerance), m)
    fam = next((f for f in m.families if f.name == "segment_disk"), None)
    if fam is None:
        raise SystemExit(f"{args.scene}: solver.rigid_soft_rows is not \"nodes_and_segments\"")
    print("| step | segment-disk rows | ending > depth inside | deepest | largest turn | turn, after - predicted, -r a²/2 (first deep row) |")
    print("|---|---|---|---|---|---|")
    for _ in range(args.steps):
        if detection.needs_detection(m, st):
            detection.detect(m, st)
        pairs = st.pairs[fam.name].copy()
        before = fam.rows(m, st.q, pairs, None)
        st, rep = run.stepper.step(st, args.pressure)
        un = np.sum(before.hn * np.where(before.dof >= 0, st.v[before.dof], 0.0), axis=1)
        predicted = before.gap + rep.h * un
        after = fam.rows(m, st.q, pairs, None)
        near = np.abs(before.gap) < 0.1 * m.diameter  # rows near contact
        turn = np.arccos(np.clip(np.sum(before.normal * after.normal, axis=1), -1.0, 1.0))
        deep = np.flatnonzero(near & (after.gap < -args.depth))
        r = m.rigid.radii[pairs[:, 1]]
        first = (f"{turn[deep[0]]:.3f}, {after.gap[deep[0]] - predicted[deep[0]]:.2e}, "
                 f"{-r[deep[0]] * turn[deep[0]] ** 2 / 2:.2e}") if deep.size else "–"
        if rep.sub_steps > 1:  # rows and velocities of the last sub-step: no prediction of the whole step
            first = f"– (taken in {rep.sub_steps} sub-steps)"
        print(f"| {st.step} | {len(pairs)} | {deep.size} | {after.gap.min():.2e} | {turn[near].max():.3f} | {first} |")
    shutil.rmtree(out.parent)


if __name__ == "__main__":
    main()
