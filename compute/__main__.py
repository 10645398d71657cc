"""``python -m compute SCENE_DIR --out OUT_DIR [--resume] [--wait] [--checkpoint-minutes M] [--bodies-outside-scene]``: run a scene.

Exit codes (docs/FORMATS.md): 0 the loading program ran (OUT/COMPLETE or OUT/INCOMPLETE), 2 an
input error (scene or output folder), 3 a numerical failure (OUT/FAILED), 4 a file of the output
folder could not be written (full disk, permission, read-only; OUT/FAILED when it could be
written), 1 anything else (a bug).
"""

from __future__ import annotations

import argparse
import sys

from compute.errors import InputError, OutputWriteError, SimulationError


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
    p.add_argument("--bodies-outside-scene", action="store_true",
                   help="accept a bodies file (bodies.file) outside the scene folder (default: refused)")
    a = p.parse_args(argv)
    if a.checkpoint_minutes is not None and not a.checkpoint_minutes > 0.0:
        p.error(f"--checkpoint-minutes: expected a positive number of minutes, got {a.checkpoint_minutes}")
    from compute.threads import configure

    try:
        configure(a.threads)
    except ValueError as exc:
        p.error(str(exc))
    from compute.run import run

    return exit_code(lambda: run(a.scene, a.out, resume=a.resume, wait=a.wait, checkpoint_minutes=a.checkpoint_minutes,
                                 bodies_outside=a.bodies_outside_scene))


def exit_code(call) -> int:
    """``call()`` (a run), its errors told on stderr in one line: the exit code of the module
    docstring. The studies' compute scripts end the same way."""
    try:
        call()
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except SimulationError as exc:
        print(f"simulation failed: {exc}", file=sys.stderr)
        return 3
    except OutputWriteError as exc:
        print(f"write failed: {exc}; what was written before is kept: free space or fix the permission, "
              f"then run again with --resume", file=sys.stderr)
        return 4
    return 0

if __name__ == "__main__":
    sys.exit(main())
