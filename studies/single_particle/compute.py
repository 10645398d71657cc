"""Single-particle study, stage 2: run WORKDIR/scene into WORKDIR/out (compute.run.run).

Same as ``python -m compute WORKDIR/scene --out WORKDIR/out``; prints the steps and run time of
every stage. Exit codes those of ``python -m compute`` (3: the run stopped with a diagnosis in
WORKDIR/out/FAILED).
"""

from __future__ import annotations

if not __package__:  # run as a file (python studies/X/stage.py): studies/entry.py
    import pathlib, sys; sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2]))
    from studies.entry import run_as_file; run_as_file(__file__)

import argparse
import sys
import time
from pathlib import Path


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--workdir", required=True, help="study folder holding scene/ (written by pre.py)")
    ap.add_argument("--resume", action="store_true", help="continue from the last checkpoint in WORKDIR/out")
    a = ap.parse_args(argv)
    from compute.__main__ import exit_code
    from compute.run import Run

    work = Path(a.workdir)

    def go() -> None:
        t0 = time.perf_counter()
        run = Run(work / "scene", work / "out", resume=a.resume)
        run.execute()
        stats = getattr(run.stepper, "stats", {})
        dt = time.perf_counter() - t0
        print(f"{run.state.step} steps in {dt:.1f} s ({1e3 * dt / max(run.state.step, 1):.1f} ms/step); {stats}")

    return exit_code(go)


if __name__ == "__main__":
    sys.exit(main())
