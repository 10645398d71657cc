"""How much the soft bodies of a run's checkpoint overlap, and whether contacts see it.

Loads RUN's checkpoint (a copy, as the other benchmarks do) and prints: the packing fraction
with the bodies' element areas (phi, T6 edges curved) and with the areas inside their
boundary-node polygons (phi_contact, what node-to-segment contacts keep apart); the area rigid
disks share with those polygons (their arcs between the soft nodes pressed on them) and phi_net,
phi_contact less that area (post.measures); the rigid disks that reach deepest into a soft
polygon (wedged between two boundary nodes); the rows of each
contact family (gaps below 0 and below -1e-3, active rows); then every soft boundary node that
lies inside another soft body's boundary polygon (found by testing all nodes against all nearby
bodies, independently of the contact lists): how many, the quantiles of their depth, whether a
node-segment candidate holds each (node, body) pair, and the deepest ones with the gap their row
reports. Why: to tell a packing fraction above 1 from the curved T6 edges (phi > 1 while
phi_contact < 1 and the penetrations are small) from contacts that miss overlaps.

    python benchmarks/experiments/overlaps.py --run studies/mixture_compaction/results/n1500/runs/k1_mu0.2_s1
"""

from __future__ import annotations

import os

for _var in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from scipy.spatial import cKDTree  # noqa: E402

sys.path.append(str(Path(__file__).resolve().parents[1]))  # benchmarks/: the shared helpers
import checkout  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--run", type=Path, required=True, help="a run folder with scene/ and out/ (with a checkpoint)")
    ap.add_argument("--top", type=int, default=10, help="deepest nodes to list")
    a = ap.parse_args()
    sys.path.insert(0, os.getcwd())  # the checkout being measured
    from compute.contact import detection
    from compute.contact.soft_rows import _inside_loop, _segment_distance2
    from post.measures import rigid_deformable_overlap, straight_areas

    with checkout.resumed(a.run) as run:
        st, m = run.state, run.model
        x = np.ascontiguousarray(m.soft_nodes(st.q))
        b = m.bounds(st.q)
        box = (b[1] - b[0]) * (b[3] - b[2])
        soft_fe = sum(g.area(st.q) for g in m.soft)
        soft_polygon = sum(straight_areas(xb, g.batch.cells).sum() for g in m.soft for xb in g.nodes(st.q))
        rigid = m.particle_area(st.q) - soft_fe
        print(f"step {st.step}: phi {(rigid + soft_fe) / box:.6f}, phi_contact {(rigid + soft_polygon) / box:.6f} "
              f"(soft bodies: element areas {soft_fe:.4f}, boundary polygons {soft_polygon:.4f})")
        meshes = [((g.node0 + g.n_nodes * np.arange(g.B)[:, None, None] + g.batch.cells).reshape(-1, g.batch.cells.shape[1]),
                   np.repeat(np.arange(g.B), len(g.batch.cells))) for g in m.soft]
        overlap = rigid_deformable_overlap(x, meshes, m.rigid.centres(st.q), m.rigid.radii) / box
        print(f"rigid disks inside soft boundary polygons: {overlap:.6f} of the box; phi_net (phi_contact less it) "
              f"{(rigid + soft_polygon) / box - overlap:.6f}")
        wedges = disk_wedges(m, st.q)
        if len(wedges):
            print(f"rigid disks reaching into soft polygons: {len(wedges)}; deepest (depth, depth / boundary segment "
                  "length, soft body, rigid body):")
            for depth, ratio, soft, disk in wedges[:a.top]:
                print(f"  {depth:.3e}  {ratio:.3f}  {soft}  {disk}")
        if detection.needs_detection(m, st):
            detection.detect(m, st)
        rows = detection.narrow_phase(m, st, branches=False)
        first = {}
        k = 0
        for fam in m.families:
            n = len(st.pairs[fam.name])
            first[fam.name] = k
            g, r = rows.gap[k:k + n], rows.impulse[k:k + n, 0]
            print(f"{fam.name}: {n} rows, min gap {g.min() if n else 0.0:.3e}, gap < 0: {(g < 0).sum()}, "
                  f"gap < -1e-3: {(g < -1e-3).sum()}, active: {(r > 0).sum()}")
            k += n
        if "node_segment" not in st.pairs:
            return
        pairs = st.pairs["node_segment"][:, :2]
        row_of = {(int(p[0]), int(p[1])): i for i, p in enumerate(pairs)}
        centres, radii = m.soft_circles(st.q)
        tree = cKDTree(centres)
        L, S = m.loop_nodes, m.loop_start
        found = []  # (node, body, depth)
        for g in L:
            for body in tree.query_ball_point(x[g], radii.max()):
                n_loop = S[body + 1] - S[body]
                if body == m.node_body[g] or np.sum((x[g] - centres[body]) ** 2) > radii[body] ** 2:
                    continue
                if _inside_loop(x[g, 0], x[g, 1], x, L, S[body], n_loop):
                    ring = L[S[body]:S[body + 1]]
                    d2 = min(_segment_distance2(*x[g], *x[a], *x[b])[0] for a, b in zip(ring, np.roll(ring, -1)))
                    found.append((int(g), int(body), float(np.sqrt(d2))))
        missed = [f for f in found if (f[0], f[1]) not in row_of]
        print(f"boundary nodes inside another body: {len(found)}, of which without a node-segment candidate: "
              f"{len(missed)}")
        if not found:
            return
        depth = np.array([f[2] for f in found])
        print("depth quantiles 0.5, 0.9, 0.99, 1: " + ", ".join(f"{v:.3g}" for v in np.quantile(depth, [0.5, 0.9, 0.99, 1])))
        for i in np.argsort(depth)[::-1][:a.top]:
            g, body, d = found[i]
            r = row_of.get((g, body))
            row = (f"row gap {rows.gap[first['node_segment'] + r]:.3e}, impulse "
                   f"{rows.impulse[first['node_segment'] + r, 0]:.3g}" if r is not None else "no row")
            print(f"  node {g} of body {m.soft_ids[m.node_body[g]]} inside body {m.soft_ids[body]}: depth {d:.3e}, {row}")


def disk_wedges(m, q) -> list[tuple[float, float, int, int]]:
    """Every (rigid disk, soft body) pair where the disk reaches into the body's boundary polygon:
    (depth = radius - distance from its centre to the boundary, depth over the body's mean
    boundary segment length, soft body id, rigid body id), deepest first. Node-to-disk contacts
    hold the nodes, not the segments between them: a disk whose arc sags between two nodes on it
    reaches in by its sagitta (about 1e-2 of a segment); much deeper, it is wedged between them."""
    x, loops, start = m.soft_nodes(q), m.loop_nodes, m.loop_start
    centres, radii = m.rigid.centres(q), m.rigid.radii
    tree = cKDTree(centres)
    out = []
    for k in range(len(start) - 1):
        a = x[loops[start[k]:start[k + 1]]]
        e = np.roll(a, -1, axis=0) - a
        reach = np.linalg.norm(a - a.mean(axis=0), axis=1).max() + radii.max()
        for d in tree.query_ball_point(a.mean(axis=0), reach):
            t = np.clip(np.einsum("ij,ij->i", centres[d] - a, e) / np.einsum("ij,ij->i", e, e), 0.0, 1.0)
            depth = radii[d] - np.linalg.norm(a + t[:, None] * e - centres[d], axis=1).min()
            if depth > 0.0:
                out.append((float(depth), float(depth / np.linalg.norm(e, axis=1).mean()), int(m.soft_ids[k]),
                            int(m.rigid.ids[d])))
    return sorted(out, reverse=True)


if __name__ == "__main__":
    main()
