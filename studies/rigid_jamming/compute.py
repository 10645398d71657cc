"""Stage 2 of the rigid jamming study: runs DIR/scene into DIR/out (frames, history, checkpoints)."""

import argparse
from pathlib import Path
from compute.run import run


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--workdir", required=True, help="study folder holding WORKDIR/scene; writes WORKDIR/out")
    p.add_argument("--resume", action="store_true", help="continue from the last checkpoint")
    a = p.parse_args(argv)
    w = Path(a.workdir)
    state = run(w / "scene", w / "out", resume=a.resume, log=print)
    print(f"done: {state.step} steps, {state.frame} frames in {w / 'out'}")


if __name__ == "__main__":
    main()
