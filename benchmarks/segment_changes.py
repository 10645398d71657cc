"""Contact rows that change between consecutive contact problems of a run, from the problems
``contact_problems.py export --count K --warm`` saved (FILE_000.npz, FILE_001.npz, …).

Each row is compared as an operator, u_n = Σ hn · v over its dofs (a sparse row of H_nᵀ): its
change is the L1 norm of the difference of the two sparse rows, so that an entry dropped for a
zero weight is no change, and a node that went over to the neighbouring segment of the other
body (the normal turned by the corner's angle) is a change of order one. Only consecutive
problems with the same rows (the same candidates) are compared; within a Newton loop the rows
stay, so the lines printed are the sub-steps' first problems. One line per such pair: the rows
changed by more than 1e-3, 1e-2 and 0.1, and of the last, those that held an impulse; how many
of them had changed by more than 0.1 at the pair before too, and of those how many are back to
the operator they had two problems before, within 0.1 (a row going over and back); and, for the changed
node–segment rows (6 dofs, weights (-1, 1 - ξ, ξ) on the node and the segment's ends), the
median and the 90th percentile of min(ξ, 1 - ξ), the node's distance from the segment's
corner along it.

    python benchmarks/contact_problems.py export --run RUN --stage 7 --count 12 --warm --file P/p.npz
    python benchmarks/segment_changes.py P/p_*.npz
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import scipy.sparse as sp

sys.path.append(str(Path(__file__).resolve().parent))  # benchmarks/: the shared helpers
from contact_problems import load  # noqa: E402

THRESHOLDS = (1e-3, 1e-2, 0.1)


def normal_operator(problem, n_dofs: int) -> sp.csr_matrix:
    """H_nᵀ (nc, n_dofs) of ``problem``'s rows (entries of dof -1 left out, repeated dofs summed)."""
    rows = np.repeat(np.arange(len(problem)), problem.dof.shape[1])
    dofs, values = problem.dof.ravel(), problem.hn.ravel()
    keep = dofs >= 0
    return sp.csr_matrix((values[keep], (rows[keep], dofs[keep])), shape=(len(problem), n_dofs))


def row_changes(a, b) -> np.ndarray:
    """|row_a - row_b|_1 per contact (nc,) of two problems with the same candidates."""
    n = int(max(a.dof.max(), b.dof.max())) + 1
    diff = normal_operator(a, n) - normal_operator(b, n)
    return np.asarray(abs(diff).sum(axis=1)).ravel()


def corner_distance(problem) -> np.ndarray:
    """min(ξ, 1 - ξ) (nc,) of the node–segment rows with both ends weighted (their six dofs
    set, none beyond; NaN for the other rows): ξ from the weights of the segment's two ends,
    |hn| of each over their sum."""
    w1 = np.hypot(problem.hn[:, 2], problem.hn[:, 3])
    w2 = np.hypot(problem.hn[:, 4], problem.hn[:, 5])
    six = np.all(problem.dof[:, :6] >= 0, axis=1) & np.all(problem.dof[:, 6:] < 0, axis=1)
    xi = w2 / np.where(six, w1 + w2, 1.0)
    return np.where(six, np.minimum(xi, 1.0 - xi), np.nan)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("files", nargs="+", type=Path)
    a = ap.parse_args()
    before = previous = None  # the last two problems compared, and the rows that changed last
    changed_last = None
    for path in sorted(a.files):
        problem, _ = load(path)
        if previous is not None and len(previous) == len(problem):
            change = row_changes(previous, problem)
            if np.any(change > 0.0):
                held = previous.impulse[:, 0] > 0.0
                turned = change > THRESHOLDS[-1]
                counts = " ".join(f"> {t:g}: {int(np.sum(change > t))}" for t in THRESHOLDS)
                line = (f"{path.name}: {len(problem)} rows, {int(held.sum())} with an impulse; changed {counts} "
                        f"(with an impulse: {int(np.sum(turned & held))})")
                if changed_last is not None and len(before) == len(problem):
                    again = turned & changed_last
                    back = again & (row_changes(before, problem) <= THRESHOLDS[-1])
                    line += f"; changed at the pair before too: {int(again.sum())}, back: {int(back.sum())}"
                d = corner_distance(previous)[turned]
                d = d[np.isfinite(d)]
                if d.size:
                    line += f"; min(xi, 1 - xi) median {np.median(d):.2g}, 90 % {np.quantile(d, 0.9):.2g}"
                print(line)
                before, changed_last = previous, turned
        previous = problem


if __name__ == "__main__":
    main()
