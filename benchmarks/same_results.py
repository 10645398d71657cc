"""Whether a change of compute leaves its results unchanged: the same scenes run by two checkouts,
their outputs compared byte for byte.

For a refactor the trajectories must stay bit-identical, so every number written must be the
same: history.csv (one row per step: time, box, φ, the Newton iterations and sweeps, ...),
frames.csv (the box of every frame), summary.json (status, steps and counts per stage) and the
last checkpoint (q, v and the contact memory). Columns or keys holding wall-clock times, if a
version writes some, are left out of the comparison (their names are listed in WALL_CLOCK).

Each checkout runs ``python -m compute SCENE --out OUT`` with PYTHONPATH set to its own tree and
NUMBA_NUM_THREADS=1 (one thread: the summation order of threaded kernels does not depend on
the machine's load), from its tree's root.

    python benchmarks/same_results.py --before /path/to/worktree-of-the-previous-commit \\
        --scene SCENE_DIR [--scene SCENE_DIR ...] --work DIR [--markdown results.md] [--reuse]

``--after`` defaults to this script's checkout. ``--reuse`` keeps an output folder of a
previous call that has a summary.json (the run finished) instead of running it again.
"""

from __future__ import annotations

import argparse
import csv
import io
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

WALL_CLOCK = {"seconds", "wall_seconds", "elapsed", "duration", "pre_seconds", "compute_seconds"}
COMPARED = ("history.csv", "frames.csv", "summary.json", "checkpoint/state.npz")


def scene_name(scene: Path) -> str:
    """A study's scene folder is DIR/scene: named after DIR; other folders by their own name."""
    return scene.parent.name if scene.name == "scene" else scene.name


def command(tree: Path, scene: Path, out: Path) -> tuple[list[str], dict]:
    env = {**os.environ, "PYTHONPATH": str(tree), "NUMBA_NUM_THREADS": "1"}
    return [sys.executable, "-m", "compute", str(scene), "--out", str(out)], env


def run(tree: Path, scene: Path, out: Path, reuse: bool) -> float | None:
    """Run the scene with the checkout ``tree`` into ``out``; its wall time (None if reused)."""
    if reuse and (out / "summary.json").is_file():
        return None
    args, env = command(tree, scene, out)
    t0 = time.monotonic()
    done = subprocess.run(args, env=env, cwd=tree, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    if done.returncode != 0 and not (out / "FAILED").is_file():
        raise SystemExit(f"{' '.join(args)} (in {tree}) exited with {done.returncode}:\n{done.stderr[-2000:]}")
    return time.monotonic() - t0


def without_wall_clock(name: str, data: bytes) -> bytes:
    """The file's bytes with any wall-clock column (csv) or key (json) removed."""
    if name.endswith(".csv"):
        rows = list(csv.reader(io.StringIO(data.decode())))
        if not rows:
            return data
        keep = [i for i, h in enumerate(rows[0]) if h not in WALL_CLOCK]
        return "\n".join(",".join(r[i] for i in keep if i < len(r)) for r in rows).encode()
    if name.endswith(".json"):
        def strip(x):
            if isinstance(x, dict):
                return {k: strip(v) for k, v in x.items() if k not in WALL_CLOCK}
            return [strip(v) for v in x] if isinstance(x, list) else x
        return json.dumps(strip(json.loads(data)), sort_keys=True).encode()
    return data


def same_file(name: str, a: Path, b: Path) -> str:
    """'same', 'DIFFERENT' (with where) or 'missing' for one output file of both runs."""
    if not a.is_file() or not b.is_file():
        return "missing" if a.is_file() != b.is_file() else "absent in both"
    if name.endswith(".npz"):
        with np.load(a) as x, np.load(b) as y:
            if sorted(x.files) != sorted(y.files):
                return f"DIFFERENT arrays {sorted(set(x.files) ^ set(y.files))}"
            bad = [k for k in x.files if x[k].dtype != y[k].dtype or x[k].shape != y[k].shape
                   or x[k].tobytes() != y[k].tobytes()]
            return "same" if not bad else f"DIFFERENT {bad}"
    da, db = without_wall_clock(name, a.read_bytes()), without_wall_clock(name, b.read_bytes())
    if da == db:
        return "same"
    la, lb = da.splitlines(), db.splitlines()
    first = next((i for i, (p, q) in enumerate(zip(la, lb)) if p != q), min(len(la), len(lb)))
    return f"DIFFERENT from line {first + 1}"


def stage_figures(out: Path) -> list[tuple[int, int, str]]:
    """(stage, steps, φ at its last step) per stage, from history.csv."""
    rows = list(csv.DictReader(open(out / "history.csv")))
    stages: dict[int, list] = {}
    for r in rows:
        stages.setdefault(int(r["stage"]), []).append(r)
    return [(s, len(rs), rs[-1]["phi"]) for s, rs in sorted(stages.items())]


def status(out: Path) -> str:
    summary = out / "summary.json"
    return json.loads(summary.read_text())["status"] if summary.is_file() else "failed"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--before", type=Path, required=True, help="a git worktree of the previous commit")
    ap.add_argument("--after", type=Path, default=Path(__file__).resolve().parents[1],
                    help="the checkout to compare (default: this script's)")
    ap.add_argument("--scene", type=Path, action="append", required=True, help="a scene folder (repeatable)")
    ap.add_argument("--work", type=Path, required=True, help="where the outputs go: WORK/{before,after}/NAME")
    ap.add_argument("--markdown", type=Path, help="also write the tables to this file")
    ap.add_argument("--reuse", action="store_true", help="keep finished outputs of a previous call")
    args = ap.parse_args(argv)
    trees = {"before": args.before.resolve(), "after": args.after.resolve()}
    lines = ["| scene | status before / after | steps before / after | seconds before / after | "
             + " | ".join(COMPARED) + " |", "|" + "---|" * (4 + len(COMPARED))]
    stage_lines = []
    identical = True
    for scene in (s.resolve() for s in args.scene):
        name = scene_name(scene)
        outs = {k: args.work.resolve() / k / name for k in trees}
        seconds = {k: run(trees[k], scene, outs[k], args.reuse) for k in trees}
        checks = [same_file(f, outs["before"] / f, outs["after"] / f) for f in COMPARED]
        identical &= all(c in ("same", "absent in both") for c in checks)
        figures = {k: stage_figures(outs[k]) for k in trees}
        steps = {k: sum(n for _, n, _ in figures[k]) for k in trees}
        secs = " / ".join("reused" if seconds[k] is None else f"{seconds[k]:.0f}" for k in trees)
        lines.append(f"| {name} | {status(outs['before'])} / {status(outs['after'])} | {steps['before']} / "
                     f"{steps['after']} | {secs} | " + " | ".join(checks) + " |")
        stage_lines += [f"\n{name}:\n", "| stage | steps before | steps after | φ before | φ after |",
                        "|---|---|---|---|---|"]
        for (s, n0, p0), (_, n1, p1) in zip(figures["before"], figures["after"]):
            stage_lines.append(f"| {s} | {n0} | {n1} | {p0} | {p1} |")
        if len(figures["before"]) != len(figures["after"]):
            stage_lines.append(f"| stages before {len(figures['before'])}, after {len(figures['after'])} | | | | |")
            identical = False
    commands = [" ".join(command(trees[k], Path("SCENE"), Path(f"WORK/{k}/NAME"))[0]) + f"   (cwd {trees[k]}, "
                f"PYTHONPATH={trees[k]}, NUMBA_NUM_THREADS=1)" for k in trees]
    text = "\n".join(lines + stage_lines) + f"\n\nall identical: {identical}\n"
    print(text)
    if args.markdown:
        args.markdown.write_text(text + "\nruns:\n\n" + "\n".join(f"    {c}" for c in commands) + "\n")
    return 0 if identical else 1


if __name__ == "__main__":
    sys.exit(main())
