"""Stage 3 of the rigid jamming study: measures of every frame (phi, Z, P from contacts and from
walls) in DIR/out/post/measures.csv, the force chains and phi, Z against P as PNGs."""

import argparse
import tomllib
from pathlib import Path

from post.__main__ import main as post_main


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--workdir", required=True, help="study folder holding WORKDIR/out; writes WORKDIR/out/post")
    a = p.parse_args(argv)
    out = Path(a.workdir) / "out"
    # the friction decides the rattler rule (2 contacts with friction, 3 without)
    mu = tomllib.loads((out / "scene.toml").read_text())["interactions"][0]["friction"]
    post_main([str(out), "--friction", str(mu)])


if __name__ == "__main__":
    main()
