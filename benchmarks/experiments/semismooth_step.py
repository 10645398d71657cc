"""A semismooth Newton on the coupled step problem (FE residual and frictionless Signorini rows
in one primal-dual active-set iteration), run in place of the toolkit's Newton loop on a scene
whose contacts are all frictionless: does linearising the contact inside the Newton take fewer
iterations per step than the fixed-point loop around the contact solver?

Per iteration, with F(v) the momentum residual of every group (soft: R_b(v) of
compute.bodies.soft; walls and rigid disks: m̂ (v − v_free)), J = ∂F/∂v (the exact
M + h²θ² K_t, indefinite where it is; or without the volumetric geometric stiffness, as the
toolkit's fallback), ũ = Hᵀ v + g̃ / (hθ) and c_i = 1 / (H_iᵀ diag(J)⁻¹ H_i):

    A = {i : r_i − c_i ũ_i > 0}     (at the first iteration optionally A = {i : r_i > 0}, the
                                     previous step's active set, from the warm-start impulses)
    [ J     −H_A ] [Δv ]   [ −F(v) ]
    [ H_Aᵀ    0  ] [r_A] = [ −ũ_A  ],   r = 0 off A,

then optionally a backtracking line search on |F − H r|² + |min(r, c ũ)|², and the toolkit's
area safeguard (newton._admissible). Converged when hθ |Δv|_∞ ≤ the Newton tolerance and the
inactive rows are open. The KKT system is solved with scipy's sparse LU (slow per iteration:
the question is the number of iterations). The step control, load control and stage logic are
the toolkit's.

It is written against the step interface before the step records (groups kept their step data
as attributes, moreau_jean dispatched to ``solve_step``): run it from a git worktree of commit
3ca8967 or earlier. Its result became compute/stepping/active_set.py.

    python benchmarks/experiments/semismooth_step.py SCENE OUT [--active-set predicted|warm]
        [--matrix exact|stabilised|hybrid] [--hybrid-switch 1e-4] [--no-line-search] [--hold-rotation]

--hold-rotation adds one equality row per soft body, its angular momentum about its centroid at
x_n (M ρ · v, ρ the rigid rotation field) held at zero by a multiplier: the rotation that
frictionless walls leave undetermined.

SCENE from `python -m studies.single_particle.pre --workdir W` (W/scene). Prints the steps,
Newton iterations and sub-steps per stage and the equilibrated φ, read from OUT/history.csv.
"""

from __future__ import annotations

import os

for _var in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import collections  # noqa: E402
import csv  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import scipy.sparse as sp  # noqa: E402
import scipy.sparse.linalg as spla  # noqa: E402


def soft_residual_and_matrix(g, v, h, theta, stabilised: bool, with_matrix: bool = True):
    """R (B, 2n) and, if ``with_matrix``, M + h²θ² K_t (B, nnz) of soft group g at velocities v
    (else None); without the volumetric geometric stiffness if ``stabilised``."""
    from compute.errors import StepFailure

    b = g.batch
    vb = v[g.dofs].reshape(g.B, -1)
    x_theta, _ = g.positions(vb)
    f, every = np.zeros((g.B, b.n_dof)), np.ones(g.B, bool)
    k = np.zeros_like(b.mass_data) if with_matrix else None
    ok = b.internal_force_and_tangent(x_theta, every, f, k) if with_matrix else b.internal_force(x_theta, every, f)
    if not ok.all():
        raise StepFailure("inverted element at x_theta")
    if with_matrix:
        b.effective_matrix(k, (h * theta) ** 2, every)
        if stabilised:
            geometric = np.zeros_like(b.mass_data)
            b.volumetric_geometric(x_theta, every, geometric)
            k -= (h * theta) ** 2 * geometric
    return g.residual(vb, f), k


def rotation_columns(model, n: int):
    """(n, B) sparse: for each soft body the column M_b ρ_b, ρ_b its rigid rotation field about
    its centroid at x_n, so that column b ᵀ v is body b's angular momentum about that centroid."""
    columns = []
    for g in model.soft:
        x = g._x_n  # (B, n_nodes, 2)
        arm = x - x.mean(axis=1, keepdims=True)
        rho = np.stack([-arm[..., 1], arm[..., 0]], axis=2).reshape(g.B, -1)
        m_rho = g.batch.mass_times(rho)
        for b in range(g.B):
            col = np.zeros(n)
            col[g.dofs.start + g.batch.n_dof * b:g.dofs.start + g.batch.n_dof * (b + 1)] = m_rho[b]
            columns.append(col)
    return sp.csr_matrix(np.array(columns).T) if columns else sp.csr_matrix((n, 0))


def make_solve_step(options):
    """A replacement of compute.stepping.newton.solve_step (same signature and results)."""
    from compute.errors import StepFailure
    from compute.solvers.report import SolveReport
    from compute.stepping import newton

    def solve_step(model, contacts, v_minus, h, theta, solver, tol, max_iterations, stats, misses_fail=True):
        n, nc = model.n_dofs, len(contacts)
        if np.any(contacts.mu > 0):
            raise SystemExit("semismooth_step.py: frictionless contacts only")
        v, v_free, linear = np.zeros(n), np.zeros(n), []
        for g in model.groups:
            if g.nonlinear:
                v[g.dofs] = v_minus[g.dofs]
            else:
                g.free_velocity(v, v_free)
                dofs, inverse = g.diagonal()
                linear.append((dofs, inverse))
                v[dofs] = v_free[dofs]
        un_minus = np.sum(contacts.hn * np.where(contacts.dof >= 0, v_minus[contacts.dof], 0.0), axis=1)
        g_term = (contacts.gap + h * (1.0 - theta) * un_minus) / (h * theta)
        keep = contacts.dof.ravel() >= 0
        for dofs, inverse in linear:  # held walls take no impulse
            keep &= ~np.isin(contacts.dof.ravel(), dofs[inverse == 0.0])
        H = sp.csr_matrix((contacts.hn.ravel()[keep], (contacts.dof.ravel()[keep],
                           np.repeat(np.arange(nc), contacts.dof.shape[1])[keep])), shape=(n, nc))

        R = rotation_columns(model, n) if options.hold_rotation else sp.csr_matrix((n, 0))
        lam = np.zeros(R.shape[1])

        def evaluate(v, stabilised, with_matrix=True):
            """F(v) (n,) and, if with_matrix, J (n, n) sparse."""
            F, rows, cols, vals = np.zeros(n), [], [], []
            for dofs, inverse in linear:
                m_hat = np.where(inverse == 0.0, 1.0, 1.0 / np.where(inverse == 0.0, 1.0, inverse))
                F[dofs] = m_hat * (v[dofs] - v_free[dofs])
                rows.append(dofs), cols.append(dofs), vals.append(m_hat)
            for g in model.soft:
                res, k = soft_residual_and_matrix(g, v, h, theta, stabilised, with_matrix)
                F[g.dofs] = res.ravel()
                if not with_matrix:
                    continue
                b = g.batch
                local_rows = np.repeat(np.arange(b.n_dof), np.diff(b.indptr))
                for i in range(g.B):
                    first = g.dofs.start + b.n_dof * i
                    rows.append(first + local_rows), cols.append(first + b.indices), vals.append(k[i])
            if not with_matrix:
                return F, None
            return F, sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n))

        def merit(v, r, lam):
            F = evaluate(v, False, with_matrix=False)[0] - H @ r - R @ lam
            c_min = np.minimum(r, c * (H.T @ v + g_term))
            spin = R.T @ v
            return float(F @ F + c_min @ c_min + spin @ spin)

        r = contacts.impulse[:, 0].copy()
        c, err = None, np.inf
        for it in range(1, max_iterations + 1):
            stats["newton_iterations"] += 1
            stabilised = options.matrix == "stabilised" or (options.matrix == "hybrid" and err > options.hybrid_switch)
            F, J = evaluate(v, stabilised)
            if c is None:
                c = 1.0 / np.maximum(np.asarray(H.multiply(H).T @ (1.0 / J.diagonal())).ravel(), 1e-300)
            u = H.T @ v + g_term
            active = (r > 0.0) if (it == 1 and options.active_set == "warm" and np.any(r > 0.0)) else (r - c * u > 0.0)
            A = np.flatnonzero(active)
            k = R.shape[1]
            kkt = sp.bmat([[J, -H[:, A], -R], [H[:, A].T, None, None], [R.T, None, None]], format="csc")
            solution = spla.spsolve(kkt, np.concatenate([-F, -u[A], -(R.T @ v)]))
            if not np.all(np.isfinite(solution)):
                raise StepFailure(f"singular KKT system at iteration {it}")
            dv, r_new = solution[:n], np.zeros(nc)
            r_new[A] = solution[n:n + len(A)]
            lam_new = solution[n + len(A):n + len(A) + k]
            if options.line_search:
                m0, dr, dl, a = merit(v, r, lam), r_new - r, lam_new - lam, 1.0
                while a > 1e-3:
                    try:
                        newton._admissible(model, v, v + a * dv, h, stats)
                        if merit(v + a * dv, r + a * dr, lam + a * dl) <= (1.0 - 1e-4 * a) * m0:
                            break
                    except StepFailure:
                        pass
                    a *= 0.5
                dv, r_new, lam_new = a * dv, r + a * dr, lam + a * dl
            v_new = newton._admissible(model, v, v + dv, h, stats)
            err = h * theta * float(np.max(np.abs(v_new - v)))
            v, r, lam = v_new, r_new, lam_new
            if err <= tol and np.all(H.T @ v + g_term >= -tol / (h * theta)):
                break
        else:
            raise StepFailure(f"semismooth Newton did not converge in {max_iterations} iterations ({err:.3g})")
        contacts.impulse[:, 0], contacts.impulse[:, 1] = r, 0.0
        return v, SolveReport(v, it, 0.0), it

    return solve_step


def summary(out: Path) -> None:
    """Steps, Newton iterations, sub-steps per stage and the stage's last φ, from history.csv."""
    stages = collections.defaultdict(list)
    for row in csv.DictReader(open(out / "history.csv")):
        stages[int(row["stage"])].append(row)
    total = 0
    print("stage | steps | Newton its | its of the first steps | sub-steps of the first steps | last phi")
    for s, rows in stages.items():
        its = [int(r["newton_iterations"]) for r in rows]
        total += sum(its)
        print(f"{s} | {len(rows)} | {sum(its)} | {its[:6]} | {[int(r['sub_steps']) for r in rows][:6]} | "
              f"{float(rows[-1]['phi']):.5f}")
    print(f"all: {sum(len(r) for r in stages.values())} steps, {total} Newton iterations; "
          f"status {next((m for m in ('COMPLETE', 'INCOMPLETE', 'FAILED') if (out / m).is_file()), 'none')}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scene", type=Path)
    ap.add_argument("out", type=Path)
    ap.add_argument("--active-set", choices=("predicted", "warm"), default="predicted")
    ap.add_argument("--matrix", choices=("exact", "stabilised", "hybrid"), default="exact")
    ap.add_argument("--hybrid-switch", type=float, default=1e-4,
                    help="hybrid: the stabilised matrix while the last correction exceeds this")
    ap.add_argument("--no-line-search", dest="line_search", action="store_false")
    ap.add_argument("--hold-rotation", action="store_true",
                    help="each soft body's angular momentum about its centroid held at zero (a multiplier)")
    a = ap.parse_args()
    import compute.stepping.moreau_jean as moreau_jean
    from compute.errors import SimulationError
    from compute.run import run

    moreau_jean.solve_step = make_solve_step(a)
    t0 = time.perf_counter()
    try:
        run(a.scene, a.out, log=lambda m: None)
    except SimulationError as exc:
        print(f"stopped: {exc}")
    print(f"{time.perf_counter() - t0:.1f} s")
    summary(a.out)


if __name__ == "__main__":
    main()
