"""``python -m compute SCENE_DIR --out OUT_DIR [--resume] [--wait] [--checkpoint-minutes M]``: run a scene."""

from __future__ import annotations

import argparse
import sys

from compute.errors import InputError, SimulationError


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m compute", description=__doc__)
    p.add_argument("scene", help="scene folder written by pre (scene.toml + bodies file)")
    p.add_argument("--out", required=True, help="output folder (frames, history, checkpoints)")
    p.add_argument("--resume", action="store_true", help="continue from the last checkpoint in --out")
    p.add_argument("--wait", action="store_true",
                   help="if another compute is writing --out, wait for it to finish instead of refusing")
    p.add_argument("--threads", type=int, default=None,
                   help="threads of the parallel kernels (default: NUMBA_NUM_THREADS, else every core)")
    p.add_argument("--checkpoint-minutes", type=float, default=None, metavar="M",
                   help="also checkpoint whenever M minutes of wall time have passed since the last checkpoint "
                        "(the trajectory then depends on when they fell; default: every "
                        "output.checkpoint_every_steps steps only)")
    a = p.parse_args(argv)
    if a.checkpoint_minutes is not None and not a.checkpoint_minutes > 0.0:
        p.error(f"--checkpoint-minutes: expected a positive number of minutes, got {a.checkpoint_minutes}")
    from compute.threads import configure

    try:
        configure(a.threads)
    except ValueError as exc:
        p.error(str(exc))
    from compute.run import run

    try:
        run(a.scene, a.out, resume=a.resume, wait=a.wait, checkpoint_minutes=a.checkpoint_minutes)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except SimulationError as exc:
        print(f"simulation failed: {exc}", file=sys.stderr)
        return 3
    return 0


if __name__ == "__main__":
    sys.exit(main())
