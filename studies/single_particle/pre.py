"""Single-particle study, stage 1: one neo-Hookean disk in a box of four pressure-driven walls.

Writes WORKDIR/scene (scene.toml + bodies.vtu) with :func:`pre.single_particle.write`: a disk of
radius R = 1 (E = 1, nu = 0.495, density 1, plane strain), meshed with about --elements
triangles (--element-type T3 or T6), in a box of four frictionless walls touching it; pressure
stages P/E log-spaced from --p-min to --p-max. Reduced units: R = 1, E = 1, density 1.

Quasi-static settings (measured, see README.md): theta = 1 (backward Euler: a step tends to an
implicit static step with contact), h = 10 (the measured optimum), walls of the disk's mass, no
wall damping; a stage is equilibrated when phi changes by less than 1e-5 (relative) over
check_every = 2 steps and the walls' inertial number is below 1e-4.
"""

from __future__ import annotations

if not __package__:  # run as a file (python studies/X/stage.py): studies/entry.py
    import pathlib, sys; sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2]))
    from studies.entry import run_as_file; run_as_file(__file__)

import argparse
import sys
from pathlib import Path

from pre.single_particle import ELEMENTS


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--workdir", required=True, help="study folder; the scene goes to WORKDIR/scene")
    ap.add_argument("--element-type", choices=("T3", "T6"), default="T6")
    ap.add_argument("--elements", type=int, default=ELEMENTS,
                    help=f"target number of triangles (default {ELEMENTS}: {ELEMENTS + 1} triangles, the measured "
                         "best T6 disk near the paper's 92, README)")
    ap.add_argument("--boundary-segments", type=int, default=None,
                    help="grade the mesh: this many boundary segments, sizes growing inward to the interior "
                         "size of the --elements mesh (resolves small contact zones; default: uniform)")
    ap.add_argument("--volumetric", choices=("standard", "mean_dilatation"), default="standard",
                    help="volumetric term (default standard; mean_dilatation: T6 only)")
    ap.add_argument("--p-min", type=float, default=1e-3, help="first P/E (default 1e-3)")
    ap.add_argument("--p-max", type=float, default=1.0, help="last P/E (default 1)")
    ap.add_argument("--stages", type=int, default=16, help="number of log-spaced stages (default 16)")
    ap.add_argument("--time-step", type=float, default=10.0, help="h in units of R sqrt(rho/E) (default 10)")
    ap.add_argument("--theta", type=float, default=1.0, help="theta of the scheme (default 1)")
    ap.add_argument("--wall-mass", type=float, default=None, help="mass of each wall (default pi, the disk's)")
    ap.add_argument("--phi-tolerance", type=float, default=1e-5, help="equilibrium: relative phi change (1e-5)")
    ap.add_argument("--check-every", type=int, default=2, help="steps between equilibrium checks")
    a = ap.parse_args(argv)
    from pre.single_particle import write

    try:
        folder = write(Path(a.workdir) / "scene", element=a.element_type, elements=a.elements,
                       boundary_segments=a.boundary_segments, volumetric=a.volumetric,
                       p_min=a.p_min, p_max=a.p_max, stages=a.stages, time_step=a.time_step, theta=a.theta,
                       wall_mass=a.wall_mass, phi_tolerance=a.phi_tolerance, check_every=a.check_every)
    except ValueError as exc:  # the mesh request (--elements, --boundary-segments)
        ap.error(str(exc))
    print(f"scene written to {folder}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
