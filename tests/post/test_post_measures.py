"""Measures on arrays and on synthetic lattices with analytically known answers."""

from __future__ import annotations

import numpy as np
import pytest

from post import measures, models
from post.frames import iter_frames
from post.table import measure_frame, measure_output
from tests.post.synthetic import RATTLER_RADIUS, disk_fan, fan_area


def test_square_lattice_is_exact(lattice):
    """Touching rigid disks, every contact fn = P d: sigma = P I, P = P_walls = P_applied,
    Z = 4 walls counting, phi = pi/4."""
    for frame in iter_frames(lattice):
        P_applied = frame.record.pressure_applied
        sigma = measures.granular_stress(frame.contacts.force, frame.contacts.branch,
                                         measures.box_area(frame.walls.position))
        np.testing.assert_allclose(sigma, P_applied * np.eye(2), rtol=1e-12, atol=1e-15)
        row = measure_frame(frame)
        assert row["P"] == pytest.approx(P_applied, rel=1e-12)
        assert row["P_walls"] == pytest.approx(P_applied, rel=1e-12)
        assert row["q"] == pytest.approx(0.0, abs=1e-12 * P_applied)
        assert row["phi"] == pytest.approx(np.pi / 4, rel=1e-12)
        assert row["Z"] == row["Z_no_rattlers"] == 4.0
        assert row["Z_bulk"] == 2 * 24 / 16          # 2 N_pp / N_p without the 16 wall contacts
        assert row["Z_constraints"] == 2 * (24 + 16) / 16  # 4 + 4/n for an n x n lattice (n = 4)
        assert (row["n_contacts"], row["n_wall_contacts"], row["n_rattlers"]) == (40, 16, 0)


def test_mixed_lattice_rattler_and_deformable_bodies(mixed_lattice):
    """T6 disks whose contacts come as two candidates each, and a rattler with a zero-force candidate."""
    rows = measure_output(mixed_lattice, min_contacts=3)
    for row, spacing in zip(rows, (1.0, 0.99, 0.98, 0.97)):
        areas = 14 * np.pi / 4 + 2 * fan_area(0.5, 16, "T6") + np.pi * RATTLER_RADIUS**2
        assert row["phi"] == pytest.approx(areas / (4 * spacing) ** 2, rel=1e-12)
        straight = 2 * (32 * 0.5 * 0.5**2 * np.sin(2 * np.pi / 32))  # T6 rims: 32-gons through corners and midsides
        assert row["phi_contact"] == pytest.approx((areas - 2 * fan_area(0.5, 16, "T6") + straight) / (4 * spacing) ** 2,
                                                   rel=1e-12)
        assert row["phi_net"] == row["phi_contact"] - row["rigid_overlap"]
        # the rigid disks touch the T6 rims (circumradius 0.5) at spacing 1, then press into them:
        # the rim polygon is inscribed, so it overlaps a disk only once the lattice is compressed
        assert abs(row["rigid_overlap"]) < 1e-15 if spacing == 1.0 else row["rigid_overlap"] > 1e-6
        assert row["P"] == pytest.approx(row["pressure_applied"], rel=1e-12)
        assert row["P_walls"] == pytest.approx(row["pressure_applied"], rel=1e-12)
        assert row["n_rattlers"] == 1 and row["n_particles"] == 17
        assert row["n_contacts"] == 40                       # split candidates count once per pair
        assert row["Z_no_rattlers"] == 4.0
        assert row["Z"] == pytest.approx(64 / 17)            # the rattler counts with z = 0
        assert row["Z_bulk"] == pytest.approx(48 / 17)


def test_bulk_modulus_column_uses_equilibrated_frames_only(mixed_lattice):
    rows = measure_output(mixed_lattice)
    equilibrated = [r for r in rows if r["equilibrated"]]
    expected = measures.bulk_modulus(np.array([r["phi"] for r in equilibrated]),
                                     np.array([r["P"] for r in equilibrated]))
    np.testing.assert_allclose([r["K"] for r in equilibrated], expected)
    assert np.isnan(rows[1]["K"])


def test_bulk_modulus_column_is_nan_when_phi_does_not_increase(lattice):
    assert all(np.isnan(row["K"]) for row in measure_output(lattice))


def test_t6_area_of_a_curved_triangle_is_exact():
    """Unit right triangle whose edge 01 bulges by h: area = 1/2 + 2/3 h (Archimedes)."""
    h = 0.3
    points = np.array([[0, 0], [1, 0], [0, 1], [0.5, -h], [0.5, 0.5], [0, 0.5]])
    area = measures.triangle_areas(points, np.array([[0, 1, 2, 3, 4, 5], [0, 2, 1, 5, 4, 3]]))
    np.testing.assert_allclose(area, 0.5 + 2 / 3 * h, rtol=1e-14)   # either orientation
    np.testing.assert_allclose(measures.triangle_areas(points, np.array([[0, 1, 2]])), 0.5, rtol=1e-14)


@pytest.mark.parametrize("sectors", [6, 12, 24, 48])
def test_disk_meshed_by_hand(sectors):
    """A fan mesh of the unit disk: T6 areas are exact for the parabolic edges and converge to pi
    as sectors^-4, T3 (the inscribed polygon) as sectors^-2."""
    for element, order in (("T3", 2), ("T6", 4)):
        points, cells = disk_fan(np.array([2.0, -1.0]), 1.0, sectors, element)
        area = measures.triangle_areas(points, cells).sum()
        assert area == pytest.approx(fan_area(1.0, sectors, element), rel=1e-13)
        assert abs(area - np.pi) < 25 * sectors**-order


@pytest.mark.parametrize("sectors", [6, 24])
def test_straight_areas_are_the_boundary_node_polygon(sectors):
    """The polygon through a fan's boundary nodes is the regular polygon inscribed in the circle,
    with 2 x sectors vertices for T6 (midside nodes on the arcs) and sectors for T3; the straight
    area of a T6 triangle with a bulging edge leaves its parabolic segment out."""
    for element, vertices in (("T3", sectors), ("T6", 2 * sectors)):
        points, cells = disk_fan(np.array([2.0, -1.0]), 1.0, sectors, element)
        inscribed = vertices * 0.5 * np.sin(2 * np.pi / vertices)
        assert measures.straight_areas(points, cells).sum() == pytest.approx(inscribed, rel=1e-13)
    points = np.array([[0, 0], [1, 0], [0, 1], [0.5, -0.3], [0.5, 0.5], [0, 0.5]])
    np.testing.assert_allclose(measures.straight_areas(points, np.array([[0, 1, 2, 3, 4, 5], [0, 2, 1, 5, 4, 3]])),
                               0.5 + 0.5 * 0.3, rtol=1e-14)


def test_particle_areas_of_rigid_and_deformable_bodies():
    points, cells = disk_fan(np.zeros(2), 0.5, 32, "T6")
    areas = measures.particle_areas(np.array([0.5, 0.5, 0.2]), np.array([False, True, True]), points,
                                    [(cells, np.zeros(len(cells), int))])
    np.testing.assert_allclose(areas, [fan_area(0.5, 32, "T6"), np.pi / 4, np.pi * 0.04])
    assert areas[0] == pytest.approx(np.pi / 4, rel=1e-5)


def test_active_contacts_threshold_is_relative_to_the_mean_force():
    fn = np.array([0.0, 1e-12, 1.0, 2.0, 3.0])
    assert measures.active_contacts(fn).tolist() == [False, False, True, True, True]
    assert measures.active_contacts(fn, threshold=0.7).tolist() == [False, False, False, True, True]
    assert not measures.active_contacts(np.zeros(3)).any()


def test_rattler_removal_cascades():
    """0 touches only 1; 1 touches 0 and 2; 2, 3, 4 form a triangle, each also touching a wall;
    5 touches nothing. With min_contacts = 2, removing 0 leaves 1 with one contact: it goes too."""
    pairs = measures.contact_pairs(np.array([1, 1, 2, 3, 4, 2, 3, 4]), np.array([0, 2, 3, 4, 2, -1, -3, -4]))
    assert measures.contacts_per_particle(pairs, 6).tolist() == [1, 2, 4, 3, 3, 0]
    assert measures.rattlers(pairs, 6, min_contacts=2).tolist() == [True, True, False, False, False, True]
    # frictionless criterion: 2 keeps 3 contacts once 1 is removed, the triangle stays
    assert measures.rattlers(pairs, 6, min_contacts=3).tolist() == [True, True, False, False, False, True]
    # 2, 3, 4 lose one contact each in turn: everything goes
    assert measures.rattlers(pairs, 6, min_contacts=4).all()


def test_contact_pairs_merge_candidates_of_the_same_pair():
    pairs = measures.contact_pairs(np.array([0, 1, 0, 2, 2]), np.array([1, 0, -2, -2, -2]))
    assert pairs.tolist() == [[-2, 0], [-2, 2], [0, 1]]
    every = np.ones(3, dtype=bool)
    assert measures.coordination(pairs, every) == pytest.approx(4 / 3)       # (2 x 1 + 2) / 3
    assert measures.coordination(pairs, every, walls=False) == pytest.approx(2 / 3)
    assert measures.coordination(pairs, np.array([True, False, True])) == pytest.approx(1.0)


def test_stress_invariants_of_a_rotated_tensor():
    c, s = np.cos(0.3), np.sin(0.3)
    rotation = np.array([[c, -s], [s, c]])
    sigma = rotation @ np.diag([3.0, 1.0]) @ rotation.T
    P, q, sigma_1, sigma_2 = measures.stress_invariants(np.stack([sigma, 2 * sigma]))
    np.testing.assert_allclose(P, [2, 4])
    np.testing.assert_allclose(q, [1, 2])
    np.testing.assert_allclose(sigma_1, [3, 6])
    np.testing.assert_allclose(sigma_2, [1, 2])


def test_bulk_modulus_of_the_platzer_law():
    """K = phi dP/dphi by centred differences against the analytic P0 phi / (phi_max - phi)."""
    phi = np.linspace(0.80, 0.90, 201)
    P = models.platzer_pressure(phi, 0.05, 0.93, 0.80)
    K = measures.bulk_modulus(phi, P)
    exact = models.log_compaction_modulus(phi, 0.05, 0.93)
    np.testing.assert_allclose(K[1:-1], exact[1:-1], rtol=1e-4)
    np.testing.assert_allclose(K[[0, -1]], exact[[0, -1]], rtol=1e-2)   # one-sided at the ends
    with pytest.raises(ValueError):
        measures.bulk_modulus(phi[::-1], P[::-1])


def test_default_min_contacts():
    assert measures.default_min_contacts(0.2) == 2 and measures.default_min_contacts(0.0) == 3


def test_frames_whose_files_are_gone_keep_their_earlier_measures(mixed_lattice):
    """A run carried without its VTU frames: their rows come from the earlier measures.csv, typed
    and valued as measured (K recomputed from them); a frame absent from it is still an error."""
    from post.errors import OutputError
    from post.frames import frame_path
    from post.table import write_measures

    measured = measure_output(mixed_lattice)
    table = write_measures(measured, mixed_lattice / "post" / "measures.csv")
    for kind in ("bodies", "contacts", "walls"):
        frame_path(mixed_lattice, kind, 1).unlink()
    kept = measure_output(mixed_lattice, kept=table)
    for a, b in zip(measured, kept):
        assert a.keys() == b.keys()
        for key in a:
            assert type(a[key]) is type(b[key]) or isinstance(a[key], float), key
            np.testing.assert_equal(a[key], b[key])
    with pytest.raises(OutputError, match="bodies"):
        measure_output(mixed_lattice)
    older = table.read_text().replace(",phi_contact,rigid_overlap,phi_net,", ",").splitlines()  # from before them
    table.write_text("\n".join([older[0]] + [",".join(np.delete(line.split(","), [8, 9, 10])) for line in older[1:]])
                     + "\n")
    before = measure_output(mixed_lattice, kept=table)
    for key in ("phi_contact", "rigid_overlap", "phi_net"):
        assert np.isnan(before[1][key]) and before[1]["phi"] == measured[1]["phi"]
        assert before[0][key] == measured[0][key]  # measured again from its frame
    frame_path(mixed_lattice, "bodies", 2).unlink()
    write_measures(measured[:2], table)
    with pytest.raises(OutputError, match="bodies"):
        measure_output(mixed_lattice, kept=table)


def _square(half: float) -> np.ndarray:
    return np.array([[-half, -half], [half, -half], [half, half], [-half, half]])


def _polygon_disk_area(polygon: np.ndarray, centre, r: float) -> float:
    a = polygon - np.asarray(centre, float)
    return float(measures.disk_fan_area(a, np.roll(a, -1, axis=0), np.full(len(a), r)).sum())


@pytest.mark.parametrize("centre, r, expected", [
    ((0.3, -0.2), 0.5, np.pi * 0.25),                     # disk inside the square
    ((0.0, 0.0), 5.0, 16.0),                               # square inside the disk
    ((2.0, 0.4), 0.5, np.pi * 0.25 / 2),                   # centred on an edge: half the disk
    ((5.0, 5.0), 0.5, 0.0),                                # apart
    ((2.3, 0.0), 0.5, 0.25 * np.arccos(0.6) - 0.3 * 0.4),  # a circular segment, d = 0.3 beyond the edge
    ((2.0, 2.0), 0.5, np.pi * 0.25 / 4),                   # centred on a corner: a quarter
])
def test_disk_polygon_intersection_is_exact(centre, r, expected):
    """Sum of disk_fan_area over a polygon's edges against the areas of circle geometry (square
    of half-width 2)."""
    assert _polygon_disk_area(_square(2.0), centre, r) == pytest.approx(expected, rel=1e-12, abs=1e-15)


def test_disk_polygon_intersection_against_sampling():
    """A random convex polygon and disk: the exact area against 4e6 uniform samples (3 sigma)."""
    rng = np.random.default_rng(5)
    angle = np.sort(rng.uniform(0, 2 * np.pi, 9))
    polygon = np.stack([np.cos(angle), np.sin(angle)], axis=1) * rng.uniform(0.8, 1.2, (9, 1))
    centre, r = np.array([0.7, 0.4]), 0.6
    exact = _polygon_disk_area(polygon, centre, r)
    from matplotlib.path import Path as MPath

    p = centre + rng.uniform(-r, r, (4_000_000, 2))
    inside = (np.sum((p - centre) ** 2, axis=1) < r**2) & MPath(polygon).contains_points(p)
    frac = inside.mean()
    assert exact == pytest.approx(frac * 4 * r**2, abs=3 * np.sqrt(frac * (1 - frac) / len(p)) * 4 * r**2)
    assert 0.1 * np.pi * r**2 < exact < 0.9 * np.pi * r**2  # a partial overlap


@pytest.mark.parametrize("element, n_edges", [("T3", 16), ("T6", 32)])
def test_boundary_edges_of_a_fan(element, n_edges):
    """The straight boundary of a 16-sector fan: 16 (T3) or 32 (T6) counter-clockwise pieces whose
    shoelace area is the straight (boundary-polygon) area."""
    points, cells = disk_fan(np.array([1.0, 2.0]), 0.5, 16, element)
    edges, cell = measures.boundary_edges(cells)
    assert len(edges) == n_edges and set(cell) == set(range(16))
    a, b = points[edges[:, 0]], points[edges[:, 1]]
    shoelace = 0.5 * np.sum(a[:, 0] * b[:, 1] - b[:, 0] * a[:, 1])
    assert shoelace == pytest.approx(measures.straight_areas(points, cells).sum(), rel=1e-12)
    assert shoelace == pytest.approx(n_edges * 0.5 * 0.25 * np.sin(2 * np.pi / n_edges), rel=1e-12)


def test_rigid_deformable_overlap():
    """Two T3 fans (16 sectors, radius 1) and three rigid disks: one inside the first fan's
    polygon, one cutting a circular segment from an edge of the second, one touching nothing.
    The total is the sum of the exact pieces."""
    fans = [disk_fan(np.array(c), 1.0, 16, "T3") for c in ((0.0, 0.0), (5.0, 0.0))]
    points = np.vstack([p for p, _ in fans])
    cells = np.vstack([fans[0][1], fans[1][1] + len(fans[0][0])])
    body = np.repeat([0, 1], 16)
    apothem, mid = np.cos(np.pi / 16), np.array([np.cos(np.pi / 16), np.sin(np.pi / 16)])  # first edge's normal
    d, r = 0.05, 0.1
    centres = np.array([[0.2, 0.1], [5.0, 0.0] + (apothem + d) * mid, [2.5, 3.0]])
    radii = np.array([0.3, r, 0.4])
    segment = r**2 * np.arccos(d / r) - d * np.sqrt(r**2 - d**2)
    got = measures.rigid_deformable_overlap(points, [(cells, body)], centres, radii)
    assert got == pytest.approx(np.pi * 0.09 + segment, rel=1e-12)
