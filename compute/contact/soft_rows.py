"""Contact rows of deformable boundaries (numba kernels): node-wall, node-disk, segment-disk,
node-segment.

Conventions of :mod:`compute.contact.rows`: body i is the *candidate* (the deformable body
owning the boundary node), body j the *antagonist* (a wall, a rigid disk, or the deformable body
owning the segment); n points from i to j, t = (-n_y, n_x), u = H^T v with
u_n = n . (v_j(x_c) - v_i(x_c)) = d gap / dt, and the impulse r = r_n n + r_t t acts on j.

Deformable nodes are numbered globally (all deformable bodies' nodes one after the other, in
the order of q); node g has the dofs ``node_dof0 + 2 g`` (x) and ``+ 1`` (y), its current
position is ``x[g]`` with ``x`` (n_nodes_total, 2). Boundary segments of a deformable body are
the straight pieces between consecutive nodes of its counter-clockwise boundary loop (corner
and midside nodes for T6); the loop of body k is ``loop_nodes[loop_start[k]:loop_start[k+1]]``
and segment s joins loop node s and s + 1 (mod the loop length). For a CCW loop the outward
normal of a segment e = x_b2 - x_b1 is (e_y, -e_x) / |e|.

Families (each kernel fills the rows ``dof, hn, ht`` (nc, MAX_DOFS), ``gap``, ``normal``,
``point`` of its candidates; the caller sets bodies, friction, branch and impulses):

- node-wall ``(g, w)``: frictionless, gap = signed distance node -> wall along the wall's
  normal; dofs (node x, node y, wall).
- node-disk ``(g, d)``, d a local rigid-disk index: gap = |x_d - x_g| - r_d, n = (x_d - x_g)/|.|;
  dofs (node x, y, disk x, y, rotation); the disk's contact point is x_d - r_d n. Only the
  nodes are kept out of the disk: where a soft body wraps around it, the disk's arc passes
  into the body's polygon between the nodes pressed on it (post.measures' rigid overlap), and
  at high pressure a disk can wedge through a stretched boundary segment into the body, deep
  enough to invert elements, in frictionless mixtures mostly (benchmarks/experiments/README.md,
  studies/mixture_compaction/README.md; benchmarks/experiments/overlaps.py lists them). The
  scene's ``solver.rigid_soft_rows = "nodes_and_segments"`` adds the segment-disk rows below,
  which keep the disk off the segments too.
- segment-disk ``(g, d)``, g the loop node that starts a boundary segment (the segment g -> its
  next loop node), d a local rigid-disk index: the disk against the segment's interior, which
  node-disk rows cannot see (a disk pressed into a soft boundary between two nodes would
  overlap the body's polygon by a circular segment). With xi the projection of x_d on the
  segment: for 0 <= xi <= 1, n = the segment's outward normal and gap = (x_d - x_p) . n - r_d,
  x_p = (1 - xi) x_g + xi x_next; otherwise xi is clamped and the row is the node-disk row of
  that end node (a redundant contact, not a wrong one). dofs (g x, y, next x, y, disk x, y,
  rotation) with weights (-(1 - xi), -xi, 1); the disk's contact point is x_d - r_d n. The
  candidates are the segments whose projection falls within the skin of [0, 1] with the disk
  in front of them. Only with ``solver.rigid_soft_rows = "nodes_and_segments"``, because of what
  they cost (benchmarks/experiments/README.md): unlike the node-disk gap, which is convex in
  the positions so that its linearisation over a step can only under-predict it, this gap is
  not: a segment that turns by an angle a within a step brings it closer than predicted by
  about r_d a² / 2, and the row's normal lags the segment's by a, which drives a frictionless
  polygon to spin; the Newton loop therefore linearises the frictionless ones again at its
  first iterate's end-of-step positions (compute.contact.end_of_step). With T6 the half-edges under pressed disks turn back and forth at every
  step (a period-2 oscillation), every step starts with many rows inside by about a half-edge's
  sagitta that the next step pushes out, and the packing creeps: a stage does not end. With T3
  there is no such oscillation, but a program takes more steps. What they buy: at high
  pressure next to no overlap of rigid and soft bodies and no wedged disk, where T3 mixtures
  with rigid disks can fail with node-disk rows alone (frictionless ones mostly, frictional ones
  now and then). What they cost in accuracy on a
  coarse mesh: the disk cannot sink into a straight segment until both its nodes move, so a
  20-node boundary is stiffer against it than the body it stands for, and φ comes out below
  the value both formulations approach as the mesh is refined, farther than node rows' φ less
  their overlap. The measurements of all this are in benchmarks/experiments/README.md
  (benchmarks/experiments/segment_gap_linearisation.py, contact_rows_refinement.py).
- node-segment ``(g, l, s)``: node g against body l, s the segment of the last rows, which the
  kernel updates in place (it walks along l's loop to the segment at minimum distance, leaving
  s only for one closer by a margin, see ``closest_segment``, then keeps it if it faces g, see
  ``facing_segment``);
  gap = (x_g - x_p) . n_out with x_p = (1 - xi) x_b1 + xi x_b2 the closest point of the
  segment (xi clamped to [0, 1]); n = -n_out; dofs (node x, y, b1 x, y, b2 x, y) with weights
  (-1, 1 - xi, xi). The normal's rotation is neglected in u_n (exact at gap = 0).
"""

from __future__ import annotations

import numba
import numpy as np

SEGMENT_HYSTERESIS = 1e-3  # a node's segment changes for one closer by this fraction of its length (closest_segment)


@numba.njit(cache=True)
def node_wall_rows(pairs, x, node_dof0, bounds, wall_dof0, normals, axes, dof, hn, ht, gap, normal, point):
    """Rows of (node g, wall w) pairs (m, 2)."""
    for c in range(pairs.shape[0]):
        g, w = pairs[c, 0], pairs[c, 1]
        nx, ny = normals[w, 0], normals[w, 1]
        tx, ty = -ny, nx
        if w < 2:
            d = (bounds[w] - x[g, 0]) * nx
        else:
            d = (bounds[w] - x[g, 1]) * ny
        gap[c] = d
        normal[c, 0], normal[c, 1] = nx, ny
        point[c, 0] = x[g, 0] + d * nx
        point[c, 1] = x[g, 1] + d * ny
        k = node_dof0 + 2 * g
        dof[c, 0], dof[c, 1], dof[c, 2] = k, k + 1, wall_dof0 + w
        hn[c, 0], hn[c, 1] = -nx, -ny
        ht[c, 0], ht[c, 1] = -tx, -ty
        hn[c, 2] = nx * axes[w, 0] + ny * axes[w, 1]
        ht[c, 2] = tx * axes[w, 0] + ty * axes[w, 1]


@numba.njit(cache=True)
def node_disk_rows(pairs, x, node_dof0, centres, radii, disk_dof0, dof, hn, ht, gap, normal, point):
    """Rows of (node g, rigid disk d) pairs (m, 2); disk d has dofs disk_dof0[d] + (0, 1, 2)."""
    for c in range(pairs.shape[0]):
        g, d = pairs[c, 0], pairs[c, 1]
        dx = centres[d, 0] - x[g, 0]
        dy = centres[d, 1] - x[g, 1]
        dist = np.sqrt(dx * dx + dy * dy)
        nx, ny = dx / dist, dy / dist
        tx, ty = -ny, nx
        gg = dist - radii[d]
        gap[c] = gg
        normal[c, 0], normal[c, 1] = nx, ny
        point[c, 0] = x[g, 0] + 0.5 * gg * nx
        point[c, 1] = x[g, 1] + 0.5 * gg * ny
        k = node_dof0 + 2 * g
        dof[c, 0], dof[c, 1] = k, k + 1
        for m in range(3):
            dof[c, 2 + m] = disk_dof0[d] + m
        hn[c, 0], hn[c, 1] = -nx, -ny
        ht[c, 0], ht[c, 1] = -tx, -ty
        hn[c, 2], hn[c, 3], hn[c, 4] = nx, ny, 0.0
        ht[c, 2], ht[c, 3], ht[c, 4] = tx, ty, -radii[d]


@numba.njit(cache=True)
def segment_disk_rows(pairs, x, node_dof0, loop_neighbours, centres, radii, disk_dof0, dof, hn, ht, gap, normal,
                      point):
    """Rows of (segment start node g, rigid disk d) pairs (m, 2); the segment ends at g's next
    loop node ``loop_neighbours[g, 1]``; disk d has dofs disk_dof0[d] + (0, 1, 2)."""
    for c in range(pairs.shape[0]):
        g, d = pairs[c, 0], pairs[c, 1]
        b = loop_neighbours[g, 1]
        ex, ey = x[b, 0] - x[g, 0], x[b, 1] - x[g, 1]
        xi = ((centres[d, 0] - x[g, 0]) * ex + (centres[d, 1] - x[g, 1]) * ey) / (ex * ex + ey * ey)
        if 0.0 <= xi <= 1.0:
            length = np.sqrt(ex * ex + ey * ey)
            nx, ny = ey / length, -ex / length  # outward normal of the CCW loop, from body i to the disk
            qx, qy = x[g, 0] + xi * ex, x[g, 1] + xi * ey
            gg = (centres[d, 0] - qx) * nx + (centres[d, 1] - qy) * ny - radii[d]
        else:
            xi = min(max(xi, 0.0), 1.0)
            qx, qy = x[g, 0] + xi * ex, x[g, 1] + xi * ey
            dx, dy = centres[d, 0] - qx, centres[d, 1] - qy
            dist = np.sqrt(dx * dx + dy * dy)
            nx, ny = dx / dist, dy / dist
            gg = dist - radii[d]
        tx, ty = -ny, nx
        gap[c] = gg
        normal[c, 0], normal[c, 1] = nx, ny
        point[c, 0] = qx + 0.5 * gg * nx
        point[c, 1] = qy + 0.5 * gg * ny
        k1, k2 = node_dof0 + 2 * g, node_dof0 + 2 * b
        dof[c, 0], dof[c, 1], dof[c, 2], dof[c, 3] = k1, k1 + 1, k2, k2 + 1
        for m in range(3):
            dof[c, 4 + m] = disk_dof0[d] + m
        hn[c, 0], hn[c, 1] = -(1.0 - xi) * nx, -(1.0 - xi) * ny
        ht[c, 0], ht[c, 1] = -(1.0 - xi) * tx, -(1.0 - xi) * ty
        hn[c, 2], hn[c, 3] = -xi * nx, -xi * ny
        ht[c, 2], ht[c, 3] = -xi * tx, -xi * ty
        hn[c, 4], hn[c, 5], hn[c, 6] = nx, ny, 0.0
        ht[c, 4], ht[c, 5], ht[c, 6] = tx, ty, -radii[d]


@numba.njit(cache=True, inline="always")
def _segment_distance2(px, py, ax, ay, bx, by):
    """Squared distance from p to the segment [a, b] and the clamped parameter xi."""
    ex, ey = bx - ax, by - ay
    l2 = ex * ex + ey * ey
    xi = ((px - ax) * ex + (py - ay) * ey) / l2 if l2 > 0.0 else 0.0
    xi = min(max(xi, 0.0), 1.0)
    qx = ax + xi * ex - px
    qy = ay + xi * ey - py
    return qx * qx + qy * qy, xi


@numba.njit(cache=True)
def closest_segment(px, py, x, loop_nodes, start, n_loop, s):
    """Walk from segment ``s`` of a loop (``loop_nodes[start:start + n_loop]``) to the segment
    at locally minimum distance from (px, py), moving only to a neighbour closer by more than
    ``SEGMENT_HYSTERESIS`` times the length of segment ``s``; returns (segment, squared distance).

    Why the margin: a node pressed into another body's polygon at one of its corners sits where
    the two segments through the corner are about equally far, and which one is closer then
    changes with the smallest motions, at every step, turning the row's normal by the corner's
    angle (18 degrees on a regular 20-node boundary) and back. In a 1500-disk mixture at high
    pressure many of the rows with an impulse did so at every sub-step, and each sub-step's first
    contact solve spent most of its iterations moving their impulses onto the turned rows
    (figures: benchmarks/results/segment_hysteresis.md). What the margin costs: a node held by
    the kept segment while the other is closer by d <= margin is kept on the kept segment's side
    of its line, at most d farther out than the closer segment would hold it (at a convex
    corner; never let in deeper there)."""
    s = s % n_loop
    a, b = loop_nodes[start + s], loop_nodes[start + (s + 1) % n_loop]
    best, _ = _segment_distance2(px, py, x[a, 0], x[a, 1], x[b, 0], x[b, 1])
    margin = SEGMENT_HYSTERESIS * np.sqrt((x[b, 0] - x[a, 0]) ** 2 + (x[b, 1] - x[a, 1]) ** 2)
    for _ in range(n_loop):
        moved = False
        for step in (-1, 1):
            t = (s + step) % n_loop
            a, b = loop_nodes[start + t], loop_nodes[start + (t + 1) % n_loop]
            d2, _ = _segment_distance2(px, py, x[a, 0], x[a, 1], x[b, 0], x[b, 1])
            if np.sqrt(d2) < np.sqrt(best) - margin:
                best, s, moved = d2, t, True
                break
        if not moved:
            break
    return s, best


@numba.njit(cache=True, inline="always")
def _faces(x, g, loop_neighbours, ax, ay, bx, by):
    """Whether segment a -> b of another body's CCW loop faces boundary node g: its outward normal
    against g's own outward vertex normal (the normal of the chord from g's previous to its next
    loop node), negative. True for a node without loop neighbours."""
    prev, nxt = loop_neighbours[g, 0], loop_neighbours[g, 1]
    if prev < 0:
        return True
    ex, ey = x[nxt, 0] - x[prev, 0], x[nxt, 1] - x[prev, 1]  # g's outward vertex normal: (ey, -ex)
    return ey * (by - ay) + ex * (bx - ax) < 0.0  # (ey, -ex) . (segment's outward normal (by - ay, -(bx - ax)))


@numba.njit(cache=True)
def facing_segment(px, py, g, x, loop_nodes, start, n_loop, s, loop_neighbours):
    """The segment of a loop that node g (at (px, py)) is in contact with: the closest one, ``s``,
    if it faces g (``_faces``); else the closer of its two neighbours that does, if one does;
    else ``s``. Why: a node at a corner of its body, near a corner of the other body, is often
    closest to a segment that does not face it (the other body's edge that continues its own
    edge, e.g. the bottom edges of two disks side by side meeting at their corners). Against
    that segment, each node is held on the wrong side of the other body: two contacts with
    parallel normals that press the two corners into each other, which with friction can lock
    (seen in a large mixture at high pressure, whatever the step size:
    benchmarks/results/corner_contacts.md). The neighbouring segment through the shared corner
    faces the node and gives the separating normal."""
    a, b = loop_nodes[start + s], loop_nodes[start + (s + 1) % n_loop]
    if _faces(x, g, loop_neighbours, x[a, 0], x[a, 1], x[b, 0], x[b, 1]):
        return s
    best, pick = np.inf, s
    for t in ((s - 1) % n_loop, (s + 1) % n_loop):
        a, b = loop_nodes[start + t], loop_nodes[start + (t + 1) % n_loop]
        if _faces(x, g, loop_neighbours, x[a, 0], x[a, 1], x[b, 0], x[b, 1]):
            d2, _ = _segment_distance2(px, py, x[a, 0], x[a, 1], x[b, 0], x[b, 1])
            if d2 < best:
                best, pick = d2, t
    return pick


@numba.njit(cache=True)
def node_segment_rows(cand, x, node_dof0, loop_nodes, loop_start, loop_neighbours, dof, hn, ht, gap, normal, point):
    """Rows of (node g, deformable body l, segment hint s) candidates (m, 3); the hint column
    is updated in place to the segment in contact (``facing_segment`` of the closest one).
    ``loop_neighbours`` (N, 2): the previous and next node of each node in its boundary loop."""
    for c in range(cand.shape[0]):
        g, l = cand[c, 0], cand[c, 1]
        start = loop_start[l]
        n_loop = loop_start[l + 1] - start
        px, py = x[g, 0], x[g, 1]
        s, _ = closest_segment(px, py, x, loop_nodes, start, n_loop, cand[c, 2])
        s = facing_segment(px, py, g, x, loop_nodes, start, n_loop, s, loop_neighbours)
        cand[c, 2] = s
        b1, b2 = loop_nodes[start + s], loop_nodes[start + (s + 1) % n_loop]
        ex, ey = x[b2, 0] - x[b1, 0], x[b2, 1] - x[b1, 1]
        length = np.sqrt(ex * ex + ey * ey)
        _, xi = _segment_distance2(px, py, x[b1, 0], x[b1, 1], x[b2, 0], x[b2, 1])
        ox, oy = ey / length, -ex / length  # outward normal of body l
        qx, qy = x[b1, 0] + xi * ex, x[b1, 1] + xi * ey
        gg = (px - qx) * ox + (py - qy) * oy
        nx, ny = -ox, -oy
        tx, ty = -ny, nx
        gap[c] = gg
        normal[c, 0], normal[c, 1] = nx, ny
        point[c, 0] = px + 0.5 * gg * nx
        point[c, 1] = py + 0.5 * gg * ny
        ka, k1, k2 = node_dof0 + 2 * g, node_dof0 + 2 * b1, node_dof0 + 2 * b2
        dof[c, 0], dof[c, 1], dof[c, 2], dof[c, 3], dof[c, 4], dof[c, 5] = ka, ka + 1, k1, k1 + 1, k2, k2 + 1
        hn[c, 0], hn[c, 1] = -nx, -ny
        ht[c, 0], ht[c, 1] = -tx, -ty
        hn[c, 2], hn[c, 3] = (1.0 - xi) * nx, (1.0 - xi) * ny
        ht[c, 2], ht[c, 3] = (1.0 - xi) * tx, (1.0 - xi) * ty
        hn[c, 4], hn[c, 5] = xi * nx, xi * ny
        ht[c, 4], ht[c, 5] = xi * tx, xi * ty


# ------------------------------------------------------------------------ node-level candidates


@numba.njit(cache=True, inline="always")
def _loop_total(body_pairs, loop_start):
    """The number of boundary-loop nodes of the bodies ``body_pairs[:, 0]`` (p, >= 1), counted
    once per pair: the most candidates a pair list can give."""
    size = 0
    for p in range(body_pairs.shape[0]):
        k = body_pairs[p, 0]
        size += loop_start[k + 1] - loop_start[k]
    return size


@numba.njit(cache=True)
def near_wall_nodes(body_walls, x, loop_nodes, loop_start, bounds, normals, skin):
    """(node, wall) pairs (m, 2) of the boundary nodes of body k within ``skin`` of wall w, for
    the body-level candidates ``body_walls`` (p, 2) = (deformable index k, wall w)."""
    out = np.empty((_loop_total(body_walls, loop_start), 2), np.int64)
    m = 0
    for p in range(body_walls.shape[0]):
        k, w = body_walls[p, 0], body_walls[p, 1]
        for i in range(loop_start[k], loop_start[k + 1]):
            g = loop_nodes[i]
            if w < 2:
                d = (bounds[w] - x[g, 0]) * normals[w, 0]
            else:
                d = (bounds[w] - x[g, 1]) * normals[w, 1]
            if d < skin:
                out[m, 0], out[m, 1] = g, w
                m += 1
    return out[:m]


@numba.njit(cache=True)
def near_disk_nodes(body_disks, x, loop_nodes, loop_start, centres, radii, skin):
    """(node, disk) pairs (m, 2) of the boundary nodes of body k within ``skin`` of rigid disk
    d, for the body-level candidates ``body_disks`` (p, 2) = (deformable index k, disk d)."""
    out = np.empty((_loop_total(body_disks, loop_start), 2), np.int64)
    m = 0
    for p in range(body_disks.shape[0]):
        k, d = body_disks[p, 0], body_disks[p, 1]
        for i in range(loop_start[k], loop_start[k + 1]):
            g = loop_nodes[i]
            dx = x[g, 0] - centres[d, 0]
            dy = x[g, 1] - centres[d, 1]
            if np.sqrt(dx * dx + dy * dy) - radii[d] < skin:
                out[m, 0], out[m, 1] = g, d
                m += 1
    return out[:m]


@numba.njit(cache=True)
def near_segment_disks(body_disks, x, loop_nodes, loop_start, centres, radii, skin):
    """(segment start node, disk) pairs (m, 2) for the body-level candidates ``body_disks`` (p, 2)
    = (deformable index k, disk d): every boundary segment of k that has disk d's centre in
    front of it (outward side), within ``skin`` of the disk's surface, and projecting within
    ``skin`` of the segment's ends."""
    out = np.empty((_loop_total(body_disks, loop_start), 2), np.int64)
    m = 0
    for p in range(body_disks.shape[0]):
        k, d = body_disks[p, 0], body_disks[p, 1]
        start, n_loop = loop_start[k], loop_start[k + 1] - loop_start[k]
        for s in range(n_loop):
            a, b = loop_nodes[start + s], loop_nodes[start + (s + 1) % n_loop]
            ex, ey = x[b, 0] - x[a, 0], x[b, 1] - x[a, 1]
            length = np.sqrt(ex * ex + ey * ey)
            along = ((centres[d, 0] - x[a, 0]) * ex + (centres[d, 1] - x[a, 1]) * ey) / length
            front = ((centres[d, 0] - x[a, 0]) * ey - (centres[d, 1] - x[a, 1]) * ex) / length
            if -skin <= along <= length + skin and 0.0 < front < radii[d] + skin:
                out[m, 0], out[m, 1] = a, d
                m += 1
    return out[:m]


@numba.njit(cache=True)
def near_segment_nodes(body_pairs, x, loop_nodes, loop_start, centres, radii, skin):
    """(node, body, segment) candidates (m, 3), both directions, for the body-level pairs
    ``body_pairs`` (p, 2) of deformable bodies: every boundary node of k within ``skin`` of a
    boundary segment of l (and of l against k), with that closest segment. ``centres``,
    ``radii`` (n_def, 2), (n_def,): bounding circles of the boundary loops."""
    size = 0
    for p in range(body_pairs.shape[0]):
        k, l = body_pairs[p, 0], body_pairs[p, 1]
        size += loop_start[k + 1] - loop_start[k] + loop_start[l + 1] - loop_start[l]
    out = np.empty((size, 3), np.int64)
    m = 0
    for p in range(body_pairs.shape[0]):
        for side in range(2):
            k, l = (body_pairs[p, 0], body_pairs[p, 1]) if side == 0 else (body_pairs[p, 1], body_pairs[p, 0])
            start = loop_start[l]
            n_loop = loop_start[l + 1] - start
            reach = radii[l] + skin
            for i in range(loop_start[k], loop_start[k + 1]):
                g = loop_nodes[i]
                px, py = x[g, 0], x[g, 1]
                dx, dy = px - centres[l, 0], py - centres[l, 1]
                if dx * dx + dy * dy >= reach * reach:
                    continue
                best = np.inf
                seg = 0
                for s in range(n_loop):
                    a, b = loop_nodes[start + s], loop_nodes[start + (s + 1) % n_loop]
                    d2, _ = _segment_distance2(px, py, x[a, 0], x[a, 1], x[b, 0], x[b, 1])
                    if d2 < best:
                        best, seg = d2, s
                if best < skin * skin or _inside_loop(px, py, x, loop_nodes, start, n_loop):
                    out[m, 0], out[m, 1], out[m, 2] = g, l, seg
                    m += 1
    return out[:m]


@numba.njit(cache=True)
def _inside_loop(px, py, x, loop_nodes, start, n_loop):
    """True if (px, py) lies inside the polygon of a boundary loop (crossing number)."""
    inside = False
    for s in range(n_loop):
        a, b = loop_nodes[start + s], loop_nodes[start + (s + 1) % n_loop]
        ay, by = x[a, 1], x[b, 1]
        if (ay > py) != (by > py):
            xc = x[a, 0] + (py - ay) / (by - ay) * (x[b, 0] - x[a, 0])
            if px < xc:
                inside = not inside
    return inside
