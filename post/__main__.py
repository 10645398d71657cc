"""``python -m post OUT_DIR [--friction MU | --min-contacts K] [--threshold T] [--young E]``

Writes OUT_DIR/post/measures.csv (one row per frame, columns in post.table), OUT_DIR/post/
force_chains.png (last frame: the force network over the rigid disks in grey and the soft ones
coloured by their pressure over E) and OUT_DIR/post/phi_Z_vs_P.png. Post does not read the scene:
the rattler threshold is --min-contacts (default 2, the frictional value), or derived from
--friction (2 contacts if MU > 0, 3 if frictionless).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from post import measures
from post.errors import OutputError
from post.frames import read_frame, read_frames_table
from post.table import measure_output, write_measures


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m post", description=__doc__.split("\n\n")[1])
    parser.add_argument("out_dir", type=Path, help="output folder written by compute")
    rattler = parser.add_mutually_exclusive_group()
    rattler.add_argument("--friction", type=float, metavar="MU",
                         help="friction coefficient: rattlers have < 2 contacts if MU > 0, < 3 if MU = 0")
    rattler.add_argument("--min-contacts", type=int, metavar="K", default=2,
                         help="rattlers have fewer than K contacts, walls counting (default 2)")
    parser.add_argument("--threshold", type=float, default=1e-9, metavar="T",
                        help="active contacts have fn > T x mean positive fn (default 1e-9)")
    parser.add_argument("--young", type=float, default=1.0, metavar="E",
                        help="Young's modulus the soft disks' pressure is divided by (default 1, the studies' unit)")
    args = parser.parse_args(argv)
    min_contacts = args.min_contacts if args.friction is None else measures.default_min_contacts(args.friction)

    from post import plots

    target = args.out_dir / "post"
    try:
        rows = measure_output(args.out_dir, min_contacts, args.threshold)
        last = read_frame(args.out_dir, read_frames_table(args.out_dir)[-1])
    except OutputError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    written = [write_measures(rows, target / "measures.csv"),
               plots.force_chains_png(last, target / "force_chains.png", args.threshold, args.young),
               plots.phi_Z_vs_P_png(rows, target / "phi_Z_vs_P.png")]
    print("\n".join(map(str, written)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
