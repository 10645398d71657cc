"""What moves in a run's frames: the soft bodies' rigid rotation and centre speed, and the rigid
disks' speed.

For every frame of ``RUN/out/frames`` (bodies_*.vtu), each soft body's node velocities are split
into the mean (its centre's velocity), a rigid rotation about its node centroid,
ω = Σ r × (v − v̄) / Σ |r|², and the rest (the deformation rate, rms over the nodes); printed: the
mean and largest |ω| and the mean centre speed of the soft bodies, the rms deformation rate, and
the rigid disks' mean and largest speed. Why: a small frictionless mixture that never came to
rest (studies/mixture_compaction/README.md, "Not done yet") had most of its motion in soft disks
turning, which nothing damps without friction.

    python benchmarks/experiments/soft_spin.py runs/mixture/runs/k0.5_mu0_s1
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np


def frame_motion(path: Path, rigid: set) -> dict:
    """The motion figures (module docstring) of one bodies frame."""
    import meshio

    m = meshio.read(path)
    x, v = m.points[:, :2], m.point_data["velocity"][:, :2]
    body = np.full(len(x), -1)
    for block, ids in zip(m.cells, m.cell_data["body"]):
        for cell, b in zip(block.data, ids):
            body[cell] = b
    omega, centre, rest, rigid_speed = [], [], [], []
    for b in np.unique(body[body >= 0]):
        mine = body == b
        if b in rigid:
            rigid_speed.append(np.linalg.norm(v[mine], axis=1).mean())
            continue
        r, dv = x[mine] - x[mine].mean(0), v[mine] - v[mine].mean(0)
        w = np.sum(r[:, 0] * dv[:, 1] - r[:, 1] * dv[:, 0]) / np.sum(r**2)
        omega.append(abs(w))
        centre.append(np.linalg.norm(v[mine].mean(0)))
        rest.append(np.sqrt(np.mean(np.sum((dv - w * np.stack([-r[:, 1], r[:, 0]], 1)) ** 2, 1))))
    return {"omega_mean": np.mean(omega), "omega_max": np.max(omega), "centre_mean": np.mean(centre),
            "deformation_rms": np.mean(rest), "rigid_mean": np.mean(rigid_speed) if rigid_speed else np.nan,
            "rigid_max": np.max(rigid_speed) if rigid_speed else np.nan}


def main() -> None:
    from compute.scene import read_scene

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run", type=Path, help="a run folder (scene/ and out/ inside)")
    a = ap.parse_args()
    frames = sorted((a.run / "out" / "frames").glob("bodies_*.vtu"))
    if not frames:
        ap.error(f"{a.run / 'out' / 'frames'}: no bodies_*.vtu frames")
    rigid = set(read_scene(a.run / "scene").rigid_ids.tolist())
    print("| frame | soft |ω| mean / max | soft centre speed | soft deformation rate rms | rigid speed mean / max |")
    print("|---|---|---|---|---|")
    for f in frames:
        d = frame_motion(f, rigid)
        print(f"| {f.stem} | {d['omega_mean']:.1e} / {d['omega_max']:.1e} | {d['centre_mean']:.1e} | "
              f"{d['deformation_rms']:.1e} | {d['rigid_mean']:.1e} / {d['rigid_max']:.1e} |")


if __name__ == "__main__":
    main()
