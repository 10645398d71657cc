"""Node-segment contact rows between deformable boundaries (compute.contact.soft_rows) at corners,
against the geometry worked out by hand."""

import numpy as np
import pytest

from compute.contact.rows import ContactRows
from compute.contact.soft_rows import SEGMENT_HYSTERESIS, node_segment_rows
from compute.model import loop_neighbours


def square_loop(x0, y0, side=1.0):
    """CCW boundary of a square with corner and midside nodes, from its bottom-left corner (8, 2)."""
    t = np.array([[0, 0], [0.5, 0], [1, 0], [1, 0.5], [1, 1], [0.5, 1], [0, 1], [0, 0.5]], float)
    return np.array([x0, y0]) + side * t


def rows(x, loops, cand):
    """ContactRows of candidates ``cand`` (m, 3) (node, body, segment hint) for boundary loops
    ``loops`` (lists of global nodes, one per body), nodes at ``x``; the hints updated in place."""
    loop_nodes = np.concatenate(loops).astype(np.int64)
    loop_start = np.concatenate([[0], np.cumsum([len(l) for l in loops])]).astype(np.int64)
    c = ContactRows.empty(len(cand))
    node_segment_rows(cand, x, 0, loop_nodes, loop_start, loop_neighbours(loop_nodes, loop_start, len(x)),
                      c.dof, c.hn, c.ht, c.gap, c.normal, c.point)
    return c


def test_loop_neighbours():
    nb = loop_neighbours(np.array([4, 5, 6, 0, 1, 2, 3]), np.array([0, 3, 7]), 8)
    np.testing.assert_array_equal(nb[[4, 5, 6, 0, 3, 7]], [[6, 5], [4, 6], [5, 4], [3, 1], [2, 0], [-1, -1]])


def test_crossed_corners_of_two_bodies_side_by_side_get_separating_normals():
    """Body 0 = [0, 1]², body 1 = [-1 + d, d] x [-e, 1 - e]: side by side, their bottom corners
    A = (0, 0) and X = (d, -e) crossed by d = 3.6e-4 (X inside body 0's left side line, just
    below its bottom line), as found in a 1500-disk mixture. Each corner node is closest to the
    other body's bottom edge, which does not face it: the contacts must use the side edges
    through the corners, normals (-1, 0) from A into body 1 and (1, 0) from X into body 0, with
    the overlap d as penetration (gap -d); not both normals pointing down."""
    d, e = 3.6e-4, 4e-6
    x = np.vstack([square_loop(0.0, 0.0), square_loop(-1.0 + d, -e)])
    loops = [np.arange(8), 8 + np.arange(8)]
    a, xn = 0, 8 + 2  # body 0's bottom-left corner, body 1's bottom-right corner
    cand = np.array([[a, 1, 1], [xn, 0, 0]], np.int64)  # hints: the bottom edges ending at X / starting at A
    c = rows(x, loops, cand)
    np.testing.assert_allclose(c.normal[0], [-1.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(c.normal[1], [1.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(c.gap, [-d, -d], rtol=1e-9)
    assert cand[0, 2] == 2 and cand[1, 2] == 7  # body 1's right side (nodes 2 -> 3), body 0's left (7 -> 0)


@pytest.mark.parametrize("shift", [0.25, 0.5, 0.75])
def test_facing_faces_keep_the_closest_segment(shift):
    """Two squares face to face across a gap of 0.01, body 1 shifted up by ``shift``: every node of
    body 0's right side within reach has body 1's left side as its segment, normal (1, 0), gap 0.01."""
    x = np.vstack([square_loop(0.0, 0.0), square_loop(1.01, shift)])
    loops = [np.arange(8), 8 + np.arange(8)]
    nodes = [n for n in (2, 3, 4) if shift <= x[n, 1] <= shift + 1.0]
    cand = np.array([[n, 1, 0] for n in nodes], np.int64)
    c = rows(x, loops, cand)
    np.testing.assert_allclose(c.normal, np.tile([1.0, 0.0], (len(nodes), 1)), atol=1e-12)
    np.testing.assert_allclose(c.gap, 0.01, rtol=1e-9)
    assert set(cand[:, 2]) <= {6, 7}  # body 1's left side: nodes 6 -> 7 -> 0


def corner_pair(node):
    """Body 0 = [0, 1]², whose corner (1, 1) joins its right side (segment 3, nodes (1, 0.5) ->
    (1, 1), outward normal (1, 0)) and its top (segment 4, (1, 1) -> (0.5, 1), normal (0, 1));
    body 1 = a unit square whose bottom-left corner node (global node 8) is at ``node``, so that
    both segments face it."""
    x = np.vstack([square_loop(0.0, 0.0), square_loop(*node)])
    return x, [np.arange(8), 8 + np.arange(8)]


@pytest.mark.parametrize("hint, side", [(3, -1.0), (4, 1.0)])
def test_a_node_at_a_corner_keeps_its_segment_across_the_bisector(hint, side):
    """A node pressed 1e-7 into body 0's corner, 1e-9 to one side of the bisector, where the other
    segment is the closer one by 2e-9: the segment of the last rows (the hint) is kept, with its
    normal and its own penetration, -(1e-7 + 1e-9). Switching there at every step is what the
    margin of closest_segment prevents: without it, the row's normal turns by 90 degrees here."""
    e, d = 1e-7, side * 1e-9
    x, loops = corner_pair((1.0 - e + d, 1.0 - e - d))
    cand = np.array([[8, 0, hint]], np.int64)
    c = rows(x, loops, cand)
    assert cand[0, 2] == hint
    normal = {3: [-1.0, 0.0], 4: [0.0, -1.0]}[hint]
    np.testing.assert_allclose(c.normal[0], normal, atol=1e-12)
    np.testing.assert_allclose(c.gap[0], -(e + abs(d)), rtol=1e-6)


@pytest.mark.parametrize("s, segment, gap", [(0.2 * SEGMENT_HYSTERESIS, 4, -0.2 * SEGMENT_HYSTERESIS),
                                             (2.0 * SEGMENT_HYSTERESIS, 3, 0.0)])
def test_a_node_sliding_round_a_corner_changes_segment_past_the_margin(s, segment, gap):
    """A node on body 0's right side a distance ``s`` below the corner, its last segment the top
    one (4): that segment is kept while the right side is closer by less than the margin
    (SEGMENT_HYSTERESIS x the top's length 0.5), and its row then reads a penetration of s, at most
    the margin, where the node touches the right side; past the margin the node goes over to
    the right side (3), normal (-1, 0), gap 0."""
    x, loops = corner_pair((1.0, 1.0 - s))
    cand = np.array([[8, 0, 4]], np.int64)
    c = rows(x, loops, cand)
    assert cand[0, 2] == segment
    np.testing.assert_allclose(c.gap[0], gap, atol=1e-15)
