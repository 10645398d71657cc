"""Cost and accuracy of one high-pressure stage of the mixture compaction against the numerical
settings (time step h, Newton tolerance), the settings behind pre.mixture.QUASI_STATIC.

A κ = 1 (all soft), μ = 0.2 mixture of N disks is compacted with the default settings up to
P/E = --p-from; from that equilibrated state (its checkpoint), the next stage, P/E = --p-to, is run
to equilibrium with each setting. Reported: steps, wall seconds, step cuts, Newton iterations and
the final φ (its spread over the settings is the settings' error; the equilibrium test itself
allows about 1e-4 relative). Writes benchmarks/results/mixture_settings.md.

    python benchmarks/experiments/mixture_settings.py [--n 30] [--p-from 0.1] [--p-to 0.3] [--workdir /tmp/mixture_settings]
"""

from __future__ import annotations

import argparse
import shutil
import time
from pathlib import Path

import numpy as np

SETTINGS = [(0.5, 1e-6), (1.0, 1e-6), (0.5, 3e-6), (0.5, 1e-5), (1.0, 1e-5)]  # the first is the reference


def prepare(work: Path, n: int, p_from: float) -> Path:
    from compute.run import run
    from compute.scene import read_scene
    from pre.jamming import jammed_rigid_scene
    from pre.mixture import compaction_parameters, mixture_scene

    base = work / "base"
    if (base / "out" / "COMPLETE").is_file():
        return base
    rigid = jammed_rigid_scene(work / "rigid", n, 0.2, 1, [1.0], overrides={"solver.time_step": 0.1}, log=lambda m: None)
    pressures = list(np.geomspace(1e-3, p_from, max(2, int(round(np.log10(p_from / 1e-3) * 2)) + 1)))
    params = compaction_parameters(read_scene(rigid).walls.bounds, 0.2, pressures)
    mixture_scene(rigid, base / "scene", 1.0, 0.2, np.random.default_rng(1), parameters=params)
    run(base / "scene", base / "out", log=lambda m: None)
    return base


def one(base: Path, work: Path, h: float, newton: float, p_to: float) -> dict:
    from compute.run import Run
    from pre.scene import copy_scene

    d = work / f"h{h:g}_n{newton:g}"
    shutil.rmtree(d, ignore_errors=True)
    copy_scene(base / "scene", d / "scene", {"solver.time_step": h, "solver.newton_tolerance": newton})
    shutil.copytree(base / "out", d / "out")
    r = Run(d / "scene", d / "out", resume=True, log=lambda m: None)
    s0, t0 = r.state.step, time.perf_counter()
    r._pressure_stage(p_to)
    stats = getattr(r.stepper, "stats", {})
    return {"h": h, "newton": newton, "steps": r.state.step - s0, "seconds": time.perf_counter() - t0,
            "phi": r.model.phi(r.state.q), "cuts": stats.get("cuts", 0), "newton_iterations": stats.get("newton_iterations", 0)}


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--n", type=int, default=30)
    p.add_argument("--p-from", type=float, default=0.1)
    p.add_argument("--p-to", type=float, default=0.3)
    p.add_argument("--workdir", default="/tmp/mixture_settings")
    a = p.parse_args(argv)
    work = Path(a.workdir)
    base = prepare(work, a.n, a.p_from)
    rows = []
    for h, newton in SETTINGS:
        rows.append(one(base, work, h, newton, a.p_to))
        print(rows[-1], flush=True)
    ref = rows[0]["phi"]
    lines = [f"# One stage P/E {a.p_from:g} -> {a.p_to:g}, N = {a.n}, kappa = 1, mu = 0.2, T3 x 92 (benchmarks/experiments/mixture_settings.py)",
             "", f"| h | Newton tol | steps | seconds | cuts | Newton it. | phi | phi - phi(h={SETTINGS[0][0]:g}, {SETTINGS[0][1]:g}) |",
             "|---|---|---|---|---|---|---|---|"]
    lines += [f"| {r['h']:g} | {r['newton']:g} | {r['steps']} | {r['seconds']:.1f} | {r['cuts']} | {r['newton_iterations']} | "
              f"{r['phi']:.6f} | {r['phi'] - ref:+.1e} |" for r in rows]
    out = Path(__file__).resolve().parents[1] / "results" / "mixture_settings.md"
    out.write_text("\n".join(lines) + "\n")
    print(out)


if __name__ == "__main__":
    main()
