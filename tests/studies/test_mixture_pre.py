"""pre.mixture: the choice of the deformable disks (volume closest to κ V_p, position-independent)
and the mixture scene written from a rigid scene (same positions and sizes, one law per pair)."""

import numpy as np
import pytest

from pre.mixture import choose_deformable, compaction_parameters, mixture_scene


@pytest.mark.parametrize("kappa", [0.0, 0.2, 0.5, 0.8, 1.0])
def test_chosen_volume_is_closest_to_kappa_vp(kappa):
    rng = np.random.default_rng(3)
    for _ in range(50):
        radii = rng.uniform(0.4, 0.6, int(rng.integers(5, 200)))
        area = np.pi * radii**2
        soft = choose_deformable(radii, kappa, rng)
        error = abs(area[soft].sum() - kappa * area.sum())
        assert error <= 0.5 * area.max() + 1e-12
        if kappa == 0.0:
            assert not soft.any()
        if kappa == 1.0:
            assert soft.all()


def test_choice_is_uniform_over_positions():
    """Every disk (hence every place in the box) is equally likely to become soft."""
    radii = np.full(60, 0.5)
    counts = np.zeros(60)
    rng = np.random.default_rng(0)
    trials = 3000
    for _ in range(trials):
        counts += choose_deformable(radii, 0.3, rng)
    freq = counts / trials
    assert np.all(np.abs(freq - 0.3) < 5 * np.sqrt(0.3 * 0.7 / trials))
    assert counts.sum() == trials * 18  # equal disks: exactly 18 of 60 every time


def test_bad_input():
    with pytest.raises(ValueError, match="kappa"):
        choose_deformable(np.ones(3), 1.5)
    with pytest.raises(ValueError, match="radii"):
        choose_deformable(np.array([1.0, -1.0]), 0.5)


def test_mixture_scene_from_rigid_scene(tmp_path):
    from compute.scene import read_scene
    from pre.scene import default_parameters, write_scene

    # a square lattice of touching rigid disks of two sizes, in its box
    n_side, r = 4, np.array([0.5, 0.45])
    xy = np.stack(np.meshgrid(np.arange(n_side) + 0.5, np.arange(n_side) + 0.5), -1).reshape(-1, 2)
    radii = r[np.arange(len(xy)) % 2]
    rigid = write_scene(tmp_path / "rigid", default_parameters((0, n_side, 0, n_side), 0.3, 1.0, [1.0]), xy, radii,
                        ["rigid"] * len(xy))
    params = compaction_parameters((0, n_side, 0, n_side), 0.3, [1e-3, 1e-2])
    folder, soft = mixture_scene(rigid, tmp_path / "mix", 0.5, 0.3, np.random.default_rng(1), parameters=params)
    scene = read_scene(folder)
    area = np.pi * radii**2
    assert abs(area[soft].sum() / area.sum() - 0.5) <= 0.5 * area.max() / area.sum()
    assert sorted(scene.material_names) == ["rigid", "soft"]
    assert np.all(scene.friction == 0.3)  # rigid-rigid, rigid-soft, soft-soft
    assert np.allclose(scene.radius, radii)
    assert {d.body for d in scene.deformable} == set(np.flatnonzero(soft))
    for d in scene.deformable:
        assert len(d.cells) == 92 and d.element == "T3"
        # same position and size: the mesh nodes on the disk's circle, its centre the rigid one
        dist = np.linalg.norm(d.points - xy[d.body], axis=1)
        assert dist.max() == pytest.approx(radii[d.body], rel=1e-9)
    assert np.allclose(scene.rigid_centres, xy[scene.rigid_ids])
    soft_material = scene.materials["soft"]
    assert (soft_material.young, soft_material.poisson, soft_material.kind) == (1.0, 0.495, "neo_hookean")
    assert scene.loading.pressures == (1e-3, 1e-2) and scene.loading.gravity == (0.0, 0.0)
