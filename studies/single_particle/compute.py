"""Single-particle study, stage 2: run WORKDIR/scene into WORKDIR/out (compute.run.run).

Same as ``python -m compute WORKDIR/scene --out WORKDIR/out``; prints the steps and run time of
every stage. Exit status 3 when the run stops with a diagnosis (WORKDIR/out/FAILED).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path



def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--workdir", required=True, help="study folder holding scene/ (written by pre.py)")
    ap.add_argument("--resume", action="store_true", help="continue from the last checkpoint in WORKDIR/out")
    a = ap.parse_args(argv)
    from compute.errors import SimulationError
    from compute.run import Run

    work = Path(a.workdir)
    t0 = time.perf_counter()
    run = Run(work / "scene", work / "out", resume=a.resume)
    try:
        run.execute()
    except SimulationError as exc:
        print(f"simulation failed: {exc}", file=sys.stderr)
        return 3
    stats = getattr(run.stepper, "stats", {})
    dt = time.perf_counter() - t0
    print(f"{run.state.step} steps in {dt:.1f} s ({1e3 * dt / max(run.state.step, 1):.1f} ms/step); {stats}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
