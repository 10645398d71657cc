"""Stage 3 of the rigid jamming study: measures of every frame (phi, Z, P from contacts and from
walls) in DIR/out/post/measures.csv, the force chains and phi, Z against P as PNGs."""

if not __package__:  # run as a file (python studies/X/stage.py): studies/entry.py
    import pathlib, sys; sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2]))
    from studies.entry import run_as_file; run_as_file(__file__)

import argparse
import sys
from pathlib import Path

from compute.scene import SCENE_FILE, read_parameters
from post.__main__ import main as post_main
from post.errors import OutputError


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--workdir", required=True, help="study folder holding WORKDIR/out; writes WORKDIR/out/post")
    a = p.parse_args(argv)
    out = Path(a.workdir) / "out"
    # the friction decides the rattler rule (2 contacts with friction, 3 without); read through the
    # scene schema, which gives an omitted friction (law = "frictionless", or mu = 0) its value
    try:
        mu = float(read_parameters(out / SCENE_FILE, OutputError)["friction"].max())
    except OutputError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    return post_main([str(out), "--friction", repr(mu)])


if __name__ == "__main__":
    sys.exit(main())
