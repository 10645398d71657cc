"""Stage 2 of the rigid jamming study: runs DIR/scene into DIR/out (frames, history, checkpoints).

Same as ``python -m compute DIR/scene --out DIR/out``, with its exit codes."""

if not __package__:  # run as a file (python studies/X/stage.py): studies/entry.py
    import pathlib, sys; sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2]))
    from studies.entry import run_as_file; run_as_file(__file__)

import argparse
import sys
from pathlib import Path

from compute.__main__ import exit_code
from compute.run import run


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--workdir", required=True, help="study folder holding WORKDIR/scene; writes WORKDIR/out")
    p.add_argument("--resume", action="store_true", help="continue from the last checkpoint")
    a = p.parse_args(argv)
    w = Path(a.workdir)

    def go() -> None:
        state = run(w / "scene", w / "out", resume=a.resume, log=print)
        print(f"done: {state.step} steps, {state.frame} frames in {w / 'out'}")

    return exit_code(go)


if __name__ == "__main__":
    sys.exit(main())
