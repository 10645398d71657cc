"""The contacts that load one body hardest in a run's next contact problem: which, how hard, where.

Resumes RUN from its checkpoint (a copy, as the other benchmarks do) with the code of the current
directory's checkout, takes ``--steps-before`` steps of its loading program, then the first
contact problem of the next step (whether that step goes on to converge or fail), and lists the
contacts touching body ``--body`` with the largest normal impulses: the bodies and nodes of each
row of H with its weights, the normal, gap and impulse, and the positions of the nodes. Also the
median impulse over the body's active contacts, for scale. The gap is shown as the problem holds
it, g̃ / (h θ) with h the step's first sub-step. For the diagnosis of a step that
fails on one body (its Newton matrix indefinite, elements over-compressed).

    python benchmarks/experiments/step_contacts.py --run studies/mixture_compaction/results/n1500/runs/k0.5_mu0.2_s1 \\
        --steps-before 8 --body 278
"""

from __future__ import annotations

import os

for _var in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.append(str(Path(__file__).resolve().parents[1]))  # benchmarks/: the shared helpers
import checkout  # noqa: E402
from sweep_cost import FirstProblem  # noqa: E402


def owner(model, d: int) -> str:
    """'body 278 node 31 x' for a global dof of a soft node, 'disk 12 dof 0' for a rigid disk's,
    'wall 2' for a wall's."""
    if d >= model.node_dof0:
        g = (d - model.node_dof0) // 2
        k = model.node_body[g]
        first = np.searchsorted(model.node_body, k)
        return f"body {model.soft_ids[k]} node {g - first} {'xy'[(d - model.node_dof0) % 2]}"
    if model.rigid.dofs.start <= d < model.rigid.dofs.stop:
        i = (d - model.rigid.dofs.start) // 3
        return f"disk {model.rigid.ids[i]} dof {(d - model.rigid.dofs.start) % 3}"
    return f"wall {d - model.walls.dofs.start}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--run", type=Path, required=True, help="a run folder with scene/ and out/ (with a checkpoint)")
    ap.add_argument("--steps-before", type=int, default=0)
    ap.add_argument("--body", type=int, required=True, help="id of a soft body")
    ap.add_argument("--top", type=int, default=4)
    a = ap.parse_args()
    sys.path.insert(0, os.getcwd())  # the checkout being measured
    from compute.stepping import load_control

    with checkout.resumed(a.run) as run:
        st, pressures, m = run.state, run.scene.loading.pressures, run.model

        def step():
            return checkout.controlled_step(load_control, run.stepper, st, pressures[st.stage - 1] if st.stage else 0.0,
                                            pressures[st.stage], lambda msg: None)[0]

        for _ in range(a.steps_before):
            st = step()
        q, depth = st.q.copy(), st.cut_depth
        print(f"step {st.step + 1}, stage {st.stage}, phi {m.phi(q):.6f}")
        run.stepper.solver = probe = FirstProblem(run.stepper.solver)
        try:
            step()
            print("the step converged")
        except Exception as exc:  # the diagnosis is what is asked for
            print(f"the step failed: {str(exc)[:300]}")
    p = probe.problem
    rows = np.where(p.dof >= 0, p.compliance.order[np.maximum(p.dof, 0)], -1)
    names = [[owner(m, int(d)) if d >= 0 else "" for d in r] for r in rows]
    mine = np.flatnonzero([any(s.startswith(f"body {a.body} ") for s in row) for row in names])
    rn = p.impulse[mine, 0]
    print(f"body {a.body}: {mine.size} contacts, {(rn > 0).sum()} with an impulse, median of those "
          f"{np.median(rn[rn > 0]) if (rn > 0).any() else 0.0:.3g}; first solve of the step, at its first "
          f"sub-step (h = {run.stepper.h} / 2**{depth})")
    for c in mine[np.argsort(rn)[::-1][:a.top]]:
        used = rows[c] >= 0
        print(f"contact {c}: r = ({p.impulse[c, 0]:.4g}, {p.impulse[c, 1]:.4g}), g / (h theta) {p.gap_term[c]:.3g}, "
              f"mu {p.mu[c]}, W_nn {p.W[c, 0, 0]:.3g}")
        for d, name, wn, wt in zip(rows[c][used], np.array(names[c])[used], p.hn[c][used], p.ht[c][used]):
            print(f"    {name:24s} hn {wn:+.4f} ht {wt:+.4f} position {q[d]:.6f}")


if __name__ == "__main__":
    main()
