"""Cost of a step with soft bodies: time per step and per Newton iteration, split by phase,
against the number of soft bodies; and the 144-disk mixture side by side with another commit.

``scaling``: for each N and element type, a κ = 1, μ = 0.2 mixture (every disk soft, 92-element
T3 or T6 meshes, the mixture study's quasi-static settings) is prepared from a jammed rigid
packing (pre.jamming, pre.mixture), then one process per case reads it, runs ``--warmup``
untimed steps at P/E = 0.01 (compilation, first detection, the first large motions), and times
the next ``--steps`` steps. Phases (compute.timing): detection (Verlet check, candidates, narrow
phase), assembly (internal forces and tangents), factorisation, solves (Newton right-hand
sides), compliance (blocks on contact dofs, Delassus blocks), contact solve (NLGS), recovery
(interior velocities), backtracking check; "other" is the rest of the step. Also reported: Newton
iterations, factorisations, NLGS sweeps per step, peak resident memory, and the bytes of the
soft groups' arrays per soft body. The exponent of per-step cost against the number of soft
bodies is fitted over N >= 144.

``compare``: ``python -m compute`` on the 144-disk κ = 0.5, μ = 0.2, T3 × 92 scene (stages P/E =
0.01, 0.03, 0.1), prepared by ``python -m studies.mixture_compaction.pre --n 144 --kappa 0.5 --mu 0.2
--element T3 --pressures 0.01 0.03 0.1``, from this checkout and from a git worktree of ``--before``,
alternately, ``--repeats`` times each; wall time of the whole command (interpreter start,
imports, numba's cached kernels, all stages); φ and the pressure from contacts and from walls of
each equilibrated stage of both.

Threads: each case runs with ``--threads`` numba threads (default 1) so that timings do not
depend on what else runs on the machine.

    python benchmarks/soft_step_cost.py scaling --n 30 144 500 1500 --elements T3 T6 --workdir W
    python benchmarks/soft_step_cost.py compare --before REV --workdir W [--repeats 3]

Writes benchmarks/results/soft_step_cost_scaling_t<threads>.{md,json} and soft_step_cost_compare_t<threads>_scene_<tree>.{md,json}.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
RESULTS = Path(__file__).resolve().parent / "results"
STATS = ("import json, sys; from compute.run import Run; r = Run(sys.argv[1], sys.argv[2], log=lambda m: None); "
         "r.execute(); print(json.dumps(r.stepper.stats))")
PHASES = ("detection", "assembly", "factorisation", "solves", "compliance", "contact solve", "recovery",
          "backtracking check")


def prepare(workdir: Path, n: int, kappa: float, mu: float, element: str, pressures, seed: int = 1) -> Path:
    """A mixture scene (jammed rigid packing, a fraction kappa made soft) in workdir; reused if there."""
    from compute.scene import read_scene
    from pre.jamming import jammed_rigid_scene
    from pre.mixture import compaction_parameters, mixture_scene

    folder = workdir / f"n{n}_k{kappa:g}_mu{mu:g}_{element}" / "scene"
    if (folder / "scene.toml").is_file():
        return folder
    rigid = workdir / f"rigid_n{n}_mu{mu:g}_s{seed}" / "scene"
    if not (rigid / "scene.toml").is_file():
        rigid = jammed_rigid_scene(rigid.parent, n, mu, seed, [1.0], overrides={"solver.time_step": 0.1},
                                   log=lambda msg: None)
    params = compaction_parameters(read_scene(rigid).walls.bounds, mu, pressures)
    mixture_scene(rigid, folder, kappa, mu, np.random.default_rng(seed), element=element, n_elements=92,
                  parameters=params)
    return folder


def measure_one(scene: Path, warmup: int, steps: int) -> dict:
    """Time ``steps`` steps after ``warmup`` (this process); phases from compute.timing."""
    import resource

    from compute.model import Model
    from compute.scene import read_scene
    from compute.stepping.moreau_jean import Stepper
    from compute.timing import TIMES

    model = Model(read_scene(scene))
    stepper = Stepper(model)
    state = model.initial_state()
    pressure = model.scene.loading.pressures[0]
    for _ in range(warmup):
        state, _ = stepper.step(state, pressure)
    seconds0, stats0 = dict(TIMES.seconds), dict(stepper.stats)
    t0 = time.perf_counter()
    for _ in range(steps):
        state, _ = stepper.step(state, pressure)
    wall = time.perf_counter() - t0
    phases = {p: TIMES.seconds.get(p, 0.0) - seconds0.get(p, 0.0) for p in PHASES}
    stats = {k: stepper.stats[k] - stats0.get(k, 0) for k in stepper.stats}
    soft_bytes = sum(_nbytes(g) + _nbytes(g.batch) + _nbytes(g.matrices) for g in model.soft)
    n_soft = sum(g.B for g in model.soft)
    return {"scene": str(scene), "n_soft": n_soft, "n_bodies": int(model.scene.n_bodies), "steps": steps,
            "wall": wall, "phases": phases, "stats": stats,
            "bytes_per_soft_body": soft_bytes / max(n_soft, 1),
            "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}


def _nbytes(obj) -> int:
    """Bytes of the numpy arrays that are attributes of ``obj`` (the group's state and work
    arrays, the batch's geometry and mass, the factors), shared ones (connectivity, patterns)
    included once."""
    return sum(v.nbytes for v in vars(obj).values() if isinstance(v, np.ndarray))


def _child_env(threads: int) -> dict:
    env = dict(os.environ)
    for var in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        env[var] = str(threads)
    return env


def scaling(args) -> None:
    rows = []
    for element in args.elements:
        for n in args.n:
            scene = prepare(args.workdir, n, 1.0, 0.2, element, [0.01])
            out = subprocess.run([sys.executable, __file__, "_one", str(scene), str(args.warmup), str(args.steps)],
                                 env=_child_env(args.threads), capture_output=True, text=True, check=True)
            row = json.loads(out.stdout.strip().splitlines()[-1])
            row["element"], row["n"] = element, n
            row["scene"] = str(scene.relative_to(args.workdir))
            rows.append(row)
            print(f"{element} N = {n}: {row['wall'] / row['steps'] * 1e3:.1f} ms per step", flush=True)
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / f"soft_step_cost_scaling_t{args.threads}.json").write_text(json.dumps(rows, indent=1) + "\n")
    (RESULTS / f"soft_step_cost_scaling_t{args.threads}.md").write_text(scaling_table(rows, args))


def scaling_table(rows: list[dict], args) -> str:
    lines = ["# Cost of a step with soft bodies against their number (κ = 1, μ = 0.2, P/E = 0.01)", "",
             f"`python benchmarks/soft_step_cost.py scaling --n {' '.join(map(str, args.n))} --elements "
             f"{' '.join(args.elements)} --warmup {args.warmup} --steps {args.steps} --threads {args.threads}`", "",
             "Milliseconds per step (per Newton iteration in brackets) by phase, after the warm-up steps.", "",
             "| element | N soft | ms/step | Newton it./step | " + " | ".join(PHASES)
             + " | other | sweeps/step | fact./step | KiB/soft body | peak RSS (MB) |",
             "|---|---|---|---|" + "---|" * len(PHASES) + "---|---|---|---|---|"]
    for r in rows:
        s, it = r["steps"], max(r["stats"]["newton_iterations"], 1)
        ph = r["phases"]
        other = r["wall"] - sum(ph.values())
        cells = [f"{1e3 * ph[p] / s:.2f} ({1e3 * ph[p] / it:.2f})" for p in PHASES]
        lines.append(f"| {r['element']} | {r['n_soft']} | {1e3 * r['wall'] / s:.1f} | {it / s:.1f} | "
                     + " | ".join(cells) + f" | {1e3 * other / s:.2f} | {r['stats']['nlgs_sweeps'] / s:.0f} | "
                     f"{r['stats']['factorizations'] / s:.0f} | {r['bytes_per_soft_body'] / 1024:.0f} | "
                     f"{r['peak_rss_mb']:.0f} |")
    lines += ["", "Fitted exponent of the cost against the number of soft bodies (N soft >= 144):", ""]
    for element in sorted({r["element"] for r in rows}):
        sel = [r for r in rows if r["element"] == element and r["n_soft"] >= 144]
        if len(sel) >= 2:
            x = np.log([r["n_soft"] for r in sel])
            per_step = np.polyfit(x, np.log([r["wall"] / r["steps"] for r in sel]), 1)[0]
            per_it = np.polyfit(x, np.log([r["wall"] / max(r["stats"]["newton_iterations"], 1) for r in sel]), 1)[0]
            phases = ", ".join(
                f"{ph} {np.polyfit(x, np.log([max(r['phases'][ph], 1e-9) / r['steps'] for r in sel]), 1)[0]:.2f}"
                for ph in PHASES)
            lines.append(f"- {element}: per step {per_step:.2f}, per Newton iteration {per_it:.2f}; per step and "
                         f"phase: {phases}")
    return "\n".join(lines) + "\n"


def compare(args) -> None:
    before = Path(args.workdir) / f"worktree_{args.before[:10]}"
    if not before.is_dir():
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", str(before), args.before], check=True)
    # the scene, prepared by the study's own stage 1 from either tree (its jamming runs compute:
    # the two trees jam the same random packing into slightly different states)
    tree = before if args.prepare_with == "before" else ROOT
    study = Path(args.workdir) / f"study144_{args.prepare_with}"
    scene = study / "runs" / "k0.5_mu0.2_s1" / "scene"
    if not (scene / "scene.toml").is_file():
        env = _child_env(args.threads)
        env["PYTHONPATH"] = str(tree)
        # trees from before the studies became a package ran their scripts by path
        pre = (["-m", "studies.mixture_compaction.pre"] if (tree / "studies" / "__init__.py").is_file()
               else [str(tree / "studies" / "mixture_compaction" / "pre.py")])
        subprocess.run([sys.executable, *pre, "--workdir",
                        str(study), "--n", "144", "--kappa", "0.5", "--mu", "0.2", "--element", "T3", "--pressures",
                        "0.01", "0.03", "0.1"], cwd=tree, env=env, check=True, capture_output=True)
    times: dict[str, list[float]] = {"before": [], "after": []}
    phis, iters = {}, {}
    for rep in range(args.repeats + 1):  # the first round is an untimed warm-up (numba caches)
        for label, tree in (("before", before), ("after", ROOT)):
            out = Path(args.workdir) / f"compare_{label}"
            env = _child_env(args.threads)
            env["PYTHONPATH"] = str(tree)
            if rep == 0:  # untimed round: the stepper's statistics, in-process (both trees keep them)
                out_json = subprocess.run([sys.executable, "-c", STATS, str(scene), str(out)], cwd=tree, env=env,
                                          check=True, capture_output=True, text=True).stdout
                iters[label] = json.loads(out_json.strip().splitlines()[-1])["newton_iterations"]
                continue
            t0 = time.perf_counter()
            subprocess.run([sys.executable, "-m", "compute", str(scene), "--out", str(out)], cwd=tree, env=env,
                           check=True, capture_output=True)
            times[label].append(time.perf_counter() - t0)
            phis[label] = _stage_measures(out)
    ratio = np.array(times["before"]) / np.array(times["after"])
    result = {"before": args.before, "scene": str(scene.relative_to(args.workdir)), "threads": args.threads, "times": times,
              "ratio": ratio.tolist(), "stages": phis, "newton_iterations": iters}
    RESULTS.mkdir(exist_ok=True)
    name = f"soft_step_cost_compare_t{args.threads}_scene_{args.prepare_with}"
    (RESULTS / f"{name}.json").write_text(json.dumps(result, indent=1) + "\n")
    lines = ["# 144-disk mixture (κ = 0.5, μ = 0.2, T3 × 92, P/E = 0.01, 0.03, 0.1): before and after", "",
             f"`python benchmarks/soft_step_cost.py compare --before {args.before} --repeats {args.repeats} "
             f"--threads {args.threads} --prepare-with {args.prepare_with}`: `python -m compute` wall time, the two "
             f"timed alternately after an untimed round; the scene prepared by the {args.prepare_with} tree's "
             "`python -m studies.mixture_compaction.pre --n 144 --kappa 0.5 --mu 0.2 --element T3 --pressures 0.01 0.03 0.1`.",
             "", f"Newton iterations (whole run): before {iters['before']}, after {iters['after']}; time per Newton "
             f"iteration (median run / iterations) before {np.median(times['before']) / max(iters['before'], 1) * 1e3:.1f} ms, "
             f"after {np.median(times['after']) / max(iters['after'], 1) * 1e3:.1f} ms.", "",
             "| | runs (s) | median (s) |", "|---|---|---|"]
    for label in ("before", "after"):
        lines.append(f"| {label} | {', '.join(f'{t:.1f}' for t in times[label])} | {np.median(times[label]):.1f} |")
    lines += ["", f"Speed-up (before / after, per pair): {', '.join(f'{r:.1f}' for r in ratio)}; "
              f"median {np.median(ratio):.1f}.", "",
              "Equilibrated stages (post.table.measure_output): φ, and the pressure from the contacts (granular "
              "stress) against the walls'.", "",
              "| stage | φ before | φ after | difference | P contacts / P walls − 1, before | after |",
              "|---|---|---|---|---|---|"]
    for k, (a, b) in enumerate(zip(phis["before"], phis["after"])):
        lines.append(f"| {k} | {a['phi']:.6f} | {b['phi']:.6f} | {b['phi'] - a['phi']:+.2e} | "
                     f"{a['P'] / a['P_walls'] - 1:+.1e} | {b['P'] / b['P_walls'] - 1:+.1e} |")
    (RESULTS / f"{name}.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


def _stage_measures(out: Path) -> list[dict]:
    """φ, P (from contacts) and P_walls of every equilibrated stage of an output folder."""
    from post.table import measure_output

    return [{k: float(r[k]) for k in ("phi", "P", "P_walls")} for r in measure_output(out, min_contacts=1)
            if r["equilibrated"]]


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="command", required=True)
    s = sub.add_parser("scaling")
    s.add_argument("--n", type=int, nargs="+", default=[30, 144, 500, 1500])
    s.add_argument("--elements", nargs="+", default=["T3", "T6"], choices=("T3", "T6"))
    s.add_argument("--warmup", type=int, default=10)
    s.add_argument("--steps", type=int, default=20)
    s.add_argument("--threads", type=int, default=1)
    s.add_argument("--workdir", type=Path, required=True)
    c = sub.add_parser("compare")
    c.add_argument("--before", required=True, help="git revision of the implementation to compare against")
    c.add_argument("--repeats", type=int, default=3)
    c.add_argument("--threads", type=int, default=1)
    c.add_argument("--prepare-with", choices=("after", "before"), default="after",
                   help="the tree whose studies.mixture_compaction.pre prepares the scene (default after)")
    c.add_argument("--workdir", type=Path, required=True)
    one = sub.add_parser("_one")
    one.add_argument("scene", type=Path)
    one.add_argument("warmup", type=int)
    one.add_argument("steps", type=int)
    a = p.parse_args(argv)
    if a.command == "_one":
        print(json.dumps(measure_one(a.scene, a.warmup, a.steps)))
    elif a.command == "scaling":
        scaling(a)
    else:
        compare(a)


if __name__ == "__main__":
    main()
