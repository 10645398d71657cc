"""Measures of a packing frame: pure functions on arrays (the definitions below).

Definitions (N_p particles, walls are not particles):

- Packing fraction phi = V_p / V: V_p the sum of the current particle areas (pi r^2 for a rigid
  disk; for a deformable disk the sum of its current element areas, T6 elements with their curved
  edges), V the area of the box bounded by the four walls.
- Contact packing fraction phi_contact = V_c / V: the same with each deformable disk's area taken
  inside the polygon of its boundary nodes, the boundary the node-to-segment contacts keep
  apart. For T3 it is phi. For T6 the polygon runs straight through the midside nodes: at rest it
  is inscribed in the curved boundary (0.41 % less area for a 40-node boundary), and where two
  bodies press, their curved edges overlap while their polygons do not. phi counts those overlaps
  twice and can pass 1 as the voids close. phi_contact does not count them; it still counts the
  overlaps the contacts leave, so it too can pass 1 (a frictionless T3 mixture at P/E = 1:
  studies/mixture_compaction/README.md).
- Rigid overlap = V_o / V: V_o the area the rigid disks share with the deformable bodies'
  boundary polygons, exactly (circle-polygon intersection). Node-to-disk contacts keep a soft
  body's nodes out of a rigid disk, not its boundary between them: where a soft body wraps
  around a rigid disk, the disk's arc passes into the polygon between the nodes pressed on it.
  This is the overlap the contacts leave (node penetrations are far shallower); it grows with
  the pressure and the fraction of soft disks (studies/mixture_compaction/README.md, φ_net).
- Net packing fraction phi_net = phi_contact - rigid overlap: the fraction of the box the
  particles cover, each point once (up to the node penetrations).
- Active contact: a contact candidate with fn > threshold x mean(fn of the candidates with fn > 0),
  threshold 1e-9 by default. Several candidates between the same two bodies (node-to-segment
  contacts of a deformable body) make one contact: contacts are counted per *pair* of bodies,
  a particle and a wall being a pair.
- z_i, the number of contacts of particle i, counts its contacts with particles and with walls.
- Rattlers: particles with z_i < min_contacts, removed iteratively (removing one lowers the z of
  its neighbours) until none is left. Usual choices: min_contacts = 2 with friction, 3 without
  (d + 1 in d = 2); it is a parameter, post does not read the friction from the scene.
- Coordination numbers, N_pp particle-particle and N_pw particle-wall contacts:
    Z             = (2 N_pp + N_pw) / N_p = <z_i>  over all particles; written 2 N_c / N_p, a wall
                    contact is half a contact (it has one particle end), so that a square lattice
                    in a box has Z = 4 exactly;
    Z_no_rattlers = the same over the non-rattlers and the contacts between them or with walls;
    Z_bulk        = 2 N_pp / N_p, particle-particle contacts only, all particles;
    Z_constraints = 2 (N_pp + N_pw) / N_p over the non-rattlers: every contact, wall contacts
                    included, counted as one constraint. This is the number to compare with
                    isostaticity: frictionless disks in a box of four pressure-driven walls have
                    2 N_p + 4 dofs less 2 global translations, so an isostatic packing has
                    Z_constraints = 4 + 4 / N_p.
- Granular stress sigma_ij = (1/V) sum_c f_i^c l_j^c (Love-Weber, paper Sec. 3 before Eq. 1),
  compression positive, over all candidates, wall contacts included with
  l = contact point - centre: it then equals the stress the walls carry at equilibrium.
  P = (sigma_1 + sigma_2)/2 (the mean stress of Eq. 1), q = (sigma_1 - sigma_2)/2.
- P_walls = mean over the four walls of force / length.
- Bulk modulus K = dP/d eps_v with eps_v = -ln(phi_0/phi), i.e. K = phi dP/dphi (paper Sec. 2).
- Pressure of a deformable body: the area-weighted mean of its cells' pressure (the frames' cell
  field, -(sigma_xx + sigma_yy)/2, compression positive) over its current cell areas: the mean
  in-plane stress of the body, what Fig. 1 colours it by.
"""

from __future__ import annotations

import numpy as np

from compute.fem.topology import signed_areas

def triangle_areas(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Current areas (n_cells,) of T3 or T6 triangles (n_cells, 3 | 6) of points (n_points, 2),
    exactly: for T6 the area bounded by the three parabolic edges (compute.fem.topology)."""
    return np.abs(signed_areas(points, cells))


def straight_areas(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Areas (n_cells,) of the polygons through all nodes of T3 or T6 triangles (n_cells, 3 | 6) of
    points (n_points, 2): for T6 the hexagon corner, midside, corner, ... (straight edges through
    the midside nodes). Summed over a body, the area inside the polygon of its boundary nodes."""
    ring = points[cells[:, [0, 3, 1, 4, 2, 5]] if cells.shape[1] == 6 else cells]  # (n_cells, k, 2)
    x, y = ring[..., 0], ring[..., 1]
    return np.abs(0.5 * np.sum(x * np.roll(y, -1, axis=1) - np.roll(x, -1, axis=1) * y, axis=1))


def particle_areas(radius: np.ndarray, rigid: np.ndarray, points: np.ndarray,
                   meshes: list[tuple[np.ndarray, np.ndarray]], straight: bool = False) -> np.ndarray:
    """Current area of each body: pi r^2 for a rigid disk, the sum of its element areas otherwise
    (``straight``: of its :func:`straight_areas`, the area inside its boundary-node polygon).

    radius (N,) nominal radii; rigid (N,) bool; points (n_points, 2); meshes a list of
    (cells (n_cells, 3 | 6), body (n_cells,)). Returns (N,).
    """
    cell_areas = straight_areas if straight else triangle_areas
    area = np.where(rigid, np.pi * radius**2, 0.0)
    for cells, body in meshes:
        area += np.bincount(body, weights=cell_areas(points, cells), minlength=len(radius))
    return area


def body_pressures(n_bodies: int, points: np.ndarray,
                   meshes: list[tuple[np.ndarray, np.ndarray, np.ndarray]]) -> np.ndarray:
    """Pressure of each deformable body, the area-weighted mean of its cell pressures (module
    docstring); NaN for a body without cells (a rigid disk).

    points (n_points, 2); meshes a list of (cells (n_cells, 3 | 6), body (n_cells,), pressure
    (n_cells,)). Returns (n_bodies,).
    """
    force = np.zeros(n_bodies)  # sum of pressure x area per body
    area = np.zeros(n_bodies)
    for cells, body, pressure in meshes:
        a = triangle_areas(points, cells)
        force += np.bincount(body, weights=pressure * a, minlength=n_bodies)
        area += np.bincount(body, weights=a, minlength=n_bodies)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(area > 0, force / area, np.nan)


_STRAIGHT_EDGES = {3: ((0, 1), (1, 2), (2, 0)), 6: ((0, 3), (3, 1), (1, 4), (4, 2), (2, 5), (5, 0))}


def boundary_edges(cells: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The straight boundary pieces of a mesh of T3 or T6 triangles (n_cells, 3 | 6): node pairs
    (k, 2), oriented like the cells (counter-clockwise cells give a counter-clockwise boundary),
    for T6 through the midside nodes; and the cell (k,) each belongs to. A piece is on the
    boundary when no other cell has it reversed."""
    local = np.array(_STRAIGHT_EDGES[cells.shape[1]])
    edges = cells[:, local].reshape(-1, 2)
    owner = np.repeat(np.arange(len(cells)), len(local))
    n = int(cells.max()) + 1
    reverse = np.isin(edges[:, 1] * n + edges[:, 0], edges[:, 0] * n + edges[:, 1])
    return edges[~reverse], owner[~reverse]


def disk_fan_area(a: np.ndarray, b: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Signed area (m,) of the intersection of the disk of radius r (m,) centred at the origin
    with the triangle (origin, a, b), a and b (m, 2): positive for a counter-clockwise triangle.
    Summed over the edges of a closed polygon (points relative to the disk's centre), the area
    of the disk inside the polygon. The edge a -> b is cut where it crosses the circle; a piece
    inside the disk adds its triangle with the origin, a piece outside the circular sector it
    subtends."""
    d = b - a
    dd = np.einsum("ij,ij->i", d, d)
    ad = np.einsum("ij,ij->i", a, d)
    disc = ad**2 - dd * (np.einsum("ij,ij->i", a, a) - r**2)  # |a + t d| = r: dd t^2 + 2 ad t + ... = 0
    root = np.sqrt(np.maximum(disc, 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = np.where(disc > 0.0, (-ad - root) / dd, 1.0)
        t2 = np.where(disc > 0.0, (-ad + root) / dd, 1.0)
    cuts = np.stack([np.zeros_like(dd), np.clip(t1, 0.0, 1.0), np.clip(t2, 0.0, 1.0), np.ones_like(dd)], axis=1)
    area = np.zeros(len(dd))
    for k in range(3):
        p = a + cuts[:, k, None] * d
        q = a + cuts[:, k + 1, None] * d
        mid = 0.5 * (p + q)
        cross = p[:, 0] * q[:, 1] - p[:, 1] * q[:, 0]
        inside = np.einsum("ij,ij->i", mid, mid) <= r**2
        sector = 0.5 * r**2 * np.arctan2(cross, np.einsum("ij,ij->i", p, q))
        area += np.where(inside, 0.5 * cross, sector)
    return area


def rigid_deformable_overlap(points: np.ndarray, meshes: list[tuple[np.ndarray, np.ndarray]], centres: np.ndarray,
                             radii: np.ndarray) -> float:
    """Total area shared by the rigid disks (centres (n_rigid, 2), radii (n_rigid,)) and the
    boundary-node polygons of the deformable bodies (points (n_points, 2), meshes as in
    :func:`particle_areas`): exact (disk–polygon intersection by :func:`disk_fan_area`), over
    every pair of a disk and a body whose bounding circles overlap."""
    from scipy.spatial import cKDTree

    if len(radii) == 0:
        return 0.0
    tree = cKDTree(centres)
    total = 0.0
    for cells, body in meshes:
        edges, cell = boundary_edges(cells)
        owner = body[cell]
        order = np.argsort(owner, kind="stable")
        edges, owner = edges[order], owner[order]
        bodies, start = np.unique(owner, return_index=True)
        count = np.diff(np.append(start, len(owner)))
        ends = points[edges]  # (k, 2, 2)
        centre = np.add.reduceat(ends[:, 0], start) / count[:, None]
        reach = np.sqrt(np.maximum.reduceat(np.sum((ends[:, 0] - np.repeat(centre, count, axis=0)) ** 2, axis=1), start))
        near = tree.query_ball_point(centre, reach + radii.max())
        pair_body = np.repeat(np.arange(len(bodies)), [len(n) for n in near])
        pair_disk = np.fromiter((d for n in near for d in n), np.int64, len(pair_body))
        hit = np.linalg.norm(centres[pair_disk] - centre[pair_body], axis=1) < reach[pair_body] + radii[pair_disk]
        pair_body, pair_disk = pair_body[hit], pair_disk[hit]
        n_edges = count[pair_body]  # every boundary piece of each pair's body, pair after pair:
        edge = np.repeat(start[pair_body] - np.cumsum(n_edges) + n_edges, n_edges) + np.arange(n_edges.sum())
        disk = np.repeat(pair_disk, n_edges)
        total += float(disk_fan_area(ends[edge, 0] - centres[disk], ends[edge, 1] - centres[disk], radii[disk]).sum())
    return total


def box_area(wall_position: np.ndarray) -> float:
    """Area of the box from the wall positions (4,) ordered left, right, bottom, top."""
    left, right, bottom, top = wall_position
    return float((right - left) * (top - bottom))


def packing_fraction(areas: np.ndarray, volume: float) -> float:
    """phi = V_p / V: areas (N,) of the particles, volume the box area."""
    return float(areas.sum() / volume)


def active_contacts(fn: np.ndarray, threshold: float = 1e-9) -> np.ndarray:
    """Mask (M,) of the candidates with fn > threshold x the mean of the positive fn (M,)."""
    positive = fn[fn > 0]
    if len(positive) == 0:
        return np.zeros(len(fn), dtype=bool)
    return fn > threshold * positive.mean()


def contact_pairs(body_i: np.ndarray, body_j: np.ndarray) -> np.ndarray:
    """Distinct unordered pairs of bodies in contact, (K, 2) int sorted per row, from the body
    ids (M,) of the active candidates; a wall (negative id) comes first in its row."""
    return np.unique(np.sort(np.stack([body_i, body_j], axis=1), axis=1), axis=0).reshape(-1, 2)


def contacts_per_particle(pairs: np.ndarray, n_bodies: int) -> np.ndarray:
    """z_i (N,): number of contacts of each particle, walls included, from pairs (K, 2)."""
    ends = pairs.ravel()
    return np.bincount(ends[ends >= 0], minlength=n_bodies)


def _pairs_among(pairs: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """The pairs (K, 2) whose particle ends are all in the mask keep (N,)."""
    return pairs[np.all((pairs < 0) | keep[np.maximum(pairs, 0)], axis=1)]


def default_min_contacts(friction: float) -> int:
    """Rattler threshold: 2 contacts with friction, 3 (= d + 1) for frictionless disks."""
    return 2 if friction > 0 else 3


def rattlers(pairs: np.ndarray, n_bodies: int, min_contacts: int) -> np.ndarray:
    """Mask (N,) of the rattlers: particles left with fewer than min_contacts contacts (walls
    counting) once the rattlers are removed, found by iterated removal. pairs (K, 2)."""
    rattler = np.zeros(n_bodies, dtype=bool)
    while True:
        z = contacts_per_particle(_pairs_among(pairs, ~rattler), n_bodies)
        new = (z < min_contacts) & ~rattler
        if not new.any():
            return rattler
        rattler |= new


def coordination(pairs: np.ndarray, particles: np.ndarray, walls: bool = True) -> float:
    """Mean number of contacts <z_i> over the particles of the mask (N,), counting only the
    contacts between them (and with walls if walls): (2 N_pp + N_pw) / N_p. pairs (K, 2)."""
    kept = _pairs_among(pairs, particles)
    if not walls:
        kept = kept[kept[:, 0] >= 0]
    n_particles = int(particles.sum())
    return float(contacts_per_particle(kept, len(particles)).sum() / n_particles) if n_particles else np.nan


def constraint_coordination(pairs: np.ndarray, particles: np.ndarray) -> float:
    """2 (N_pp + N_pw) / N_p over the particles of the mask (N,): each contact among them, or with a
    wall, counted as one constraint. pairs (K, 2)."""
    kept = _pairs_among(pairs, particles)
    n_particles = int(particles.sum())
    return 2.0 * len(kept) / n_particles if n_particles else np.nan


def granular_stress(force: np.ndarray, branch: np.ndarray, volume: float) -> np.ndarray:
    """sigma_ij = (1/V) sum_c f_i l_j (compression positive): force, branch (M, 2) -> (2, 2)."""
    return force.T @ branch / volume


def stress_invariants(sigma: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Principal stresses sigma_1 >= sigma_2 of the symmetric part of sigma (..., 2, 2), and
    P = (sigma_1 + sigma_2)/2 (Eq. 1), q = (sigma_1 - sigma_2)/2. Returns (P, q, sigma_1, sigma_2)."""
    eig = np.linalg.eigvalsh(0.5 * (sigma + np.swapaxes(sigma, -1, -2)))
    sigma_2, sigma_1 = eig[..., 0], eig[..., 1]
    return 0.5 * (sigma_1 + sigma_2), 0.5 * (sigma_1 - sigma_2), sigma_1, sigma_2


def wall_pressure(force: np.ndarray, length: np.ndarray) -> float:
    """P_walls: mean over the walls of normal force / length; force, length (4,)."""
    return float(np.mean(force / length))


def bulk_modulus(phi: np.ndarray, pressure: np.ndarray) -> np.ndarray:
    """K = dP/d eps_v = phi dP/dphi (eps_v = -ln(phi_0/phi)), by centred differences (np.gradient,
    second order on uneven spacing; one-sided at both ends) along a compaction curve.

    phi, pressure (n,), phi strictly increasing (n >= 2), e.g. the equilibrated stages. Returns (n,).
    Noise: an error delta on each phi gives a relative error ~ delta / dphi on K, dphi the spacing
    between stages. Stages equilibrated to a relative phi variation of 1e-4 make K meaningful only
    while dphi >> 1e-4 phi; near phi_max, where dphi shrinks as P grows, K becomes noisy.
    """
    phi, pressure = np.asarray(phi, dtype=float), np.asarray(pressure, dtype=float)
    if len(phi) < 2 or np.any(np.diff(phi) <= 0):
        raise ValueError("bulk_modulus needs at least 2 points with strictly increasing phi")
    return phi * np.gradient(pressure, phi)
