"""Stage 1 of the rigid jamming study: a polydisperse rigid-disk packing jammed by a gentle
stress-controlled compression (run with the compute stage), written as DIR/scene."""

if not __package__:  # run as a file (python studies/X/stage.py): studies/entry.py
    import pathlib, sys; sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2]))
    from studies.entry import run_as_file; run_as_file(__file__)

import argparse

from pre.jamming import jammed_rigid_scene


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--workdir", required=True, help="study folder: writes WORKDIR/scene (and WORKDIR/jamming)")
    p.add_argument("--n", type=int, default=200, help="number of disks (default 200)")
    p.add_argument("--mu", type=float, default=0.2, help="inter-particle friction (default 0.2)")
    p.add_argument("--seed", type=int, default=1, help="random seed of the loose packing")
    p.add_argument("--pressures", type=float, nargs="+", default=[1.0, 2.0, 4.0],
                   help="pressure stages of the compute run, in units of rho <d>^2 / t^2 (default 1 2 4)")
    a = p.parse_args(argv)
    folder = jammed_rigid_scene(a.workdir, a.n, a.mu, a.seed, a.pressures,
                                overrides={"solver.time_step": 0.1}, log=print)
    print(f"scene written: {folder}")


if __name__ == "__main__":
    main()
