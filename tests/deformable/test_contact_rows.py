"""Contact rows of deformable boundaries: u_n = H_n^T v is the rate of the gap, conventions of
compute.contact.rows, candidates found by the broad phase and warm-start memory."""

import numpy as np
import pytest

from compute.contact import detection
from tests.deformable import scenes


@pytest.fixture(scope="module")
def mixed(tmp_path_factory):
    """Two T6 disks and a rigid disk near each other and near the walls (gaps below the skin)."""
    folder = tmp_path_factory.mktemp("mixed")
    a = scenes.disk(30, "T6", centre=(0.0, 0.0))
    b = scenes.disk(30, "T6", centre=(2.02, 0.1), turn=0.3)
    params = scenes.parameters((-1.02, 4.0, -1.02, 3.0))
    params["solver"]["skin"] = 0.1
    scenes.write(folder, params, soft=[a, b], rigid=[((0.3, 1.55), 0.5)])
    return scenes.load(folder)


def contacts_at(model, state):
    state.q_detect = None
    detection.detect(model, state)
    return detection.narrow_phase(model, state)


def soft_families(model):
    return [f.name for f in model.families if "soft" in f.kinds]


def test_every_family_is_found(mixed):
    model, _, state = mixed
    c = contacts_at(model, state)
    fams = {f: len(state.pairs[f]) for f in soft_families(model)}
    assert all(n > 0 for n in fams.values()), fams
    assert len(c) == sum(len(state.pairs[f.name]) for f in model.families)
    # both directions of node-segment contacts between bodies 0 and 1
    seg = state.pairs["node_segment"]
    assert set(model.node_body[seg[:, 0]]) == {0, 1} and set(seg[:, 1]) == {0, 1}
    assert set(c.body_j[c.body_j < 0]) <= {-1, -3}  # walls xmin and ymin only


def test_normal_rows_are_the_gap_rate(mixed):
    """gap(q + eps v) - gap(q) = eps H_n^T v + O(eps^2) for random v (walls and rigid included)."""
    model, _, state = mixed
    c0 = contacts_at(model, state)
    rng = np.random.default_rng(3)
    v = rng.normal(size=len(state.q))
    eps = 1e-7
    q0 = state.q.copy()
    state.q = q0 + eps * v
    c1 = detection.narrow_phase(model, state)  # same candidates (no re-detection)
    state.q = q0
    un = np.sum(np.where(c0.dof >= 0, c0.hn * v[np.maximum(c0.dof, 0)], 0.0), axis=1)
    rate = (c1.gap - c0.gap) / eps
    # node-segment: the normal's rotation is neglected, exact only at zero gap: error ~ gap
    tol = 1e-5 + 2.0 * np.abs(c0.gap) * np.abs(v).max()
    assert np.all(np.abs(rate - un) <= tol)
    exact = (c0.body_j < 0) | np.isin(c0.body_j, model.rigid.ids)
    np.testing.assert_allclose(rate[exact], un[exact], atol=1e-5)


def test_rows_conventions(mixed):
    """Unit normals from i to j, impulses on j: H_n of a rigid translation of the pair is zero,
    and a wall row moves the wall dof along the normal."""
    model, _, state = mixed
    c = contacts_at(model, state)
    np.testing.assert_allclose(np.linalg.norm(c.normal, axis=1), 1.0)
    both = c.body_j >= 0
    for k in np.flatnonzero(both):
        v = np.zeros(len(state.q))
        v[model.node_dof0::2] = 1.0  # every deformable node moves along +x
        rig = model.rigid.dof_of()
        v[rig] = 1.0  # and every rigid disk too
        used = c.dof[k] >= 0
        assert abs(np.sum(c.hn[k, used] * v[c.dof[k, used]])) < 1e-12
    # deformable bodies have their centroid as centre: branch of a pair = centroid_j - centroid_i
    centres = model.centres(state.q)
    np.testing.assert_allclose(c.branch[both], centres[c.body_j[both]] - centres[c.body_i[both]])


def test_warm_start_memory_survives_redetection(mixed):
    model, _, state = mixed
    contacts_at(model, state)
    for f in soft_families(model):
        state.impulses[f] = np.arange(2 * len(state.pairs[f]), dtype=float).reshape(-1, 2) + 1.0
    kept = {f: (state.pairs[f].copy(), state.impulses[f].copy()) for f in soft_families(model)}
    state.q_detect = None
    detection.detect(model, state)
    for f, (pairs, imp) in kept.items():
        np.testing.assert_array_equal(state.pairs[f][:, :2], pairs[:, :2])
        np.testing.assert_array_equal(state.impulses[f], imp)


def test_verlet_criterion(mixed):
    model, _, state = mixed
    contacts_at(model, state)
    assert not detection.needs_detection(model, state)
    skin = model.scene.solver.skin * model.diameter
    node = model.loop_nodes[3]
    state.q[model.node_dof0 + 2 * node] += 0.6 * skin
    assert detection.needs_detection(model, state)
