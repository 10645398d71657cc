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



def test_t3_compactions_keep_disks_off_the_segments():
    """Compactions of T3 disks, with or without friction, hold rigid disks off the soft segments
    as well as the nodes (the wedging of pre.mixture.rigid_soft_rows); T6 disks keep the node
    rows alone; an explicit override wins; a scene without both kinds builds no segment family."""
    from compute.contact.families import families_of

    box = (0.0, 4.0, 0.0, 4.0)
    assert compaction_parameters(box, 0.0, [1e-3])["solver"]["rigid_soft_rows"] == "nodes_and_segments"
    assert compaction_parameters(box, 0.2, [1e-3])["solver"]["rigid_soft_rows"] == "nodes_and_segments"
    assert compaction_parameters(box, 0.0, [1e-3], element="T6")["solver"]["rigid_soft_rows"] == "nodes"
    forced = compaction_parameters(box, 0.0, [1e-3], {"solver.rigid_soft_rows": "nodes"})
    assert forced["solver"]["rigid_soft_rows"] == "nodes"
    assert "segment_disk" in {f.name for f in families_of({"rigid", "soft", "wall"}, "nodes_and_segments")}
    assert "segment_disk" not in {f.name for f in families_of({"soft", "wall"}, "nodes_and_segments")}

# ------------------------------------------------------------------ the study's pre.py: the preparation

def _pre(workdir, *extra):
    import subprocess
    import sys
    from pathlib import Path

    return subprocess.run([sys.executable, "-m", "studies.mixture_compaction.pre", "--workdir", str(workdir),
                           "--n", "16", "--kappa", "0.5", "1", "--mu", "0", "0.2", "--pressures", "0.001", *extra],
                          cwd=Path(__file__).resolve().parents[2], capture_output=True, text=True)


def _phi_of_scene(scene) -> float:
    """Σ π r² of the rigid disks + Σ of the soft triangles' areas (shoelace) from bodies.vtu, over
    the box of scene.toml: computed here without the toolkit."""
    import tomllib

    import meshio

    mesh = meshio.read(scene / "bodies.vtu")
    area = 0.0
    for block, radius in zip(mesh.cells, mesh.cell_data["radius"]):
        if block.type == "vertex":
            area += float(np.sum(np.pi * np.asarray(radius) ** 2))
        else:
            assert block.type == "triangle"
            a, b, c = (mesh.points[block.data[:, k], :2] for k in range(3))
            area += float(np.sum(np.abs((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1])
                                        - (c[:, 0] - a[:, 0]) * (b[:, 1] - a[:, 1]))) / 2)
    w = tomllib.loads((scene / "scene.toml").read_text())["walls"]
    return area / ((w["xmax"] - w["xmin"]) * (w["ymax"] - w["ymin"]))


def _Z_of_last_frame(out, n_particles: int, threshold: float = 1e-9) -> float:
    """2 N_c / N_p (a wall contact counting half) from the last frame's contacts VTU: one contact
    per pair of bodies with fn > threshold x the mean positive fn."""
    import meshio

    from compute.output import read_frame_rows

    frame = int(read_frame_rows(out / "frames.csv")[-1]["frame"])
    mesh = meshio.read(out / "frames" / f"contacts_{frame:05d}.vtu")
    data = {k: np.concatenate([np.asarray(b).reshape(len(b), -1)[:, 0] for b in mesh.cell_data[k]])
            for k in ("body_i", "body_j", "fn")}
    active = data["fn"] > threshold * data["fn"][data["fn"] > 0].mean()
    pairs = {tuple(sorted((int(i), int(j)))) for i, j in zip(data["body_i"][active], data["body_j"][active])}
    return sum(2 if i >= 0 else 1 for i, j in pairs) / n_particles


def test_shared_preparation_one_sample_for_both_frictions(tmp_path):
    """The shared preparation (the default) with the 1500-disk study's jamming friction: one packing
    jammed with μ = 0.2, one choice of soft disks, compacted with μ = 0 and 0.2; φ₀ and Z₀ of that
    prepared sample, the same for both frictions: φ₀ as post measures it (soft disks by their
    element areas), Z₀ counted on the jamming's last frame."""
    import json

    from compute.scene import read_scene

    done = _pre(tmp_path, "--jamming-mu", "0.2")
    assert done.returncode == 0, done.stderr
    study = json.loads((tmp_path / "study.json").read_text())
    assert (study["preparation"], study["jamming_mu"]) == ("shared", 0.2)
    (jam,) = study["jamming"]
    assert jam["mu"] == 0.2 and jam["measures"]["min_contacts"] == 2
    runs = {(r["kappa"], r["mu"]): r for r in study["runs"]}
    assert len(runs) == 4 and {r["jamming_mu"] for r in runs.values()} == {0.2}
    Z = _Z_of_last_frame(tmp_path / "rigid" / "mu0.2_s1" / "jamming" / "out", 16)
    for kappa in (0.5, 1):
        frictionless, frictional = runs[(kappa, 0.0)], runs[(kappa, 0.2)]
        assert frictionless["prepared"] == frictional["prepared"]
        a, b = (read_scene(tmp_path / r["scene"]) for r in (frictionless, frictional))
        assert [d.body for d in a.deformable] == [d.body for d in b.deformable]  # the same soft disks
        prepared = frictional["prepared"]
        assert prepared["phi"] == pytest.approx(_phi_of_scene(tmp_path / frictional["scene"]), rel=1e-12)
        assert prepared["Z"] == pytest.approx(Z, rel=1e-12)
        assert prepared["Z_no_rattlers"] >= prepared["Z"]  # rattlers have fewer contacts than the mean
    # T3 disks are their inscribed polygons: all-soft phi below the rigid packing's by that ratio
    # for 20 boundary segments, sin(2 pi/20) / (2 pi/20) (the 92-triangle reference mesh)
    ratio = runs[(1, 0.2)]["prepared"]["phi"] / jam["measures"]["phi"]
    assert ratio == pytest.approx(np.sin(2 * np.pi / 20) / (2 * np.pi / 20), rel=1e-9)

    bad = _pre(tmp_path, "--kappa", "0.2", "--add", "--preparation", "per-friction")
    assert bad.returncode == 2 and "field 'preparation'" in bad.stderr
    bad = _pre(tmp_path, "--kappa", "0.2", "--add", "--jamming-mu", "0.2", "--relax", "none")
    assert bad.returncode == 2 and "field 'relax'" in bad.stderr


def _box_area(scene) -> float:
    import tomllib

    w = tomllib.loads((scene / "scene.toml").read_text())["walls"]
    return (w["xmax"] - w["xmin"]) * (w["ymax"] - w["ymin"])


@pytest.mark.parametrize("relax", ["rigid", "none"])
def test_frictionless_runs_start_from_the_relaxed_packing(tmp_path, relax):
    """--relax rigid: the μ = 0 runs start from the shared packing jammed again with rigid
    frictionless disks, the μ = 0.2 runs from the shared packing; φ₀ stays the prepared sample's.
    Pushed by constant pressure from rest, rigid disks that dissipate can only lower P × box area
    (no elastic energy to store), so the relaxed box is not larger than the jammed one."""
    import json

    done = _pre(tmp_path, "--jamming-mu", "0.2", "--relax", relax)
    assert done.returncode == 0, done.stderr
    study = json.loads((tmp_path / "study.json").read_text())
    runs = {(r["kappa"], r["mu"]): r for r in study["runs"]}
    jammed = tmp_path / "rigid" / "mu0.2_s1" / "scene"
    if relax == "none":
        assert study["relaxed"] == []
        assert {_box_area(tmp_path / r["scene"]) for r in runs.values()} == {_box_area(jammed)}
        return
    (record,) = study["relaxed"]
    assert (record["mu"], record["from_mu"], record["equilibrated"]) == (0.0, 0.2, True)
    relaxed = tmp_path / record["scene"]
    assert _box_area(relaxed) <= _box_area(jammed) * (1 + 1e-9)
    for kappa in (0.5, 1):
        frictionless, frictional = runs[(kappa, 0.0)], runs[(kappa, 0.2)]
        assert _box_area(tmp_path / frictionless["scene"]) == _box_area(relaxed)
        assert _box_area(tmp_path / frictional["scene"]) == _box_area(jammed)
        assert frictionless["prepared"] == frictional["prepared"]
        assert frictional["prepared"]["phi"] == pytest.approx(_phi_of_scene(tmp_path / frictional["scene"]), rel=1e-12)


def test_per_friction_preparation_jams_each_friction(tmp_path):
    import json

    for option in (["--jamming-mu", "0.2"], ["--relax", "rigid"]):
        refused = _pre(tmp_path, "--preparation", "per-friction", *option)
        assert refused.returncode == 2 and option[0] in refused.stderr
    done = _pre(tmp_path, "--preparation", "per-friction")
    assert done.returncode == 0, done.stderr
    study = json.loads((tmp_path / "study.json").read_text())
    assert study["preparation"] == "per-friction" and study["jamming_mu"] is None
    assert sorted(j["mu"] for j in study["jamming"]) == [0.0, 0.2]
    assert {j["mu"]: j["measures"]["min_contacts"] for j in study["jamming"]} == {0.0: 3, 0.2: 2}
    for r in study["runs"]:
        assert r["jamming_mu"] == r["mu"]
        Z = _Z_of_last_frame(tmp_path / "rigid" / f"mu{r['mu']:g}_s1" / "jamming" / "out", 16)
        assert r["prepared"]["Z"] == pytest.approx(Z, rel=1e-12)
        assert r["prepared"]["phi"] == pytest.approx(_phi_of_scene(tmp_path / r["scene"]), rel=1e-12)


def test_frictional_compaction_solves_contacts_to_the_looser_tolerance():
    """Frictional compactions solve their contacts to 1e-3 (pre.mixture.frictional_tolerance),
    frictionless ones to QUASI_STATIC's 1e-4; an explicit override wins at either friction."""
    from pre.mixture import QUASI_STATIC

    box = (0.0, 4.0, 0.0, 4.0)
    assert compaction_parameters(box, 0.2, [1e-3])["solver"]["contact_tolerance"] == 1e-3
    assert compaction_parameters(box, 0.0, [1e-3])["solver"]["contact_tolerance"] == QUASI_STATIC[
        "solver.contact_tolerance"] == 1e-4
    for mu in (0.0, 0.2):
        forced = compaction_parameters(box, mu, [1e-3], {"solver.contact_tolerance": 1e-5})
        assert forced["solver"]["contact_tolerance"] == 1e-5


def test_large_frictionless_compaction_screens_its_contacts():
    """Frictionless compactions of more than AUTO_QP_BODIES bodies (MPRGP's) solve on the
    contacts that can close (pre.mixture.frictionless_screening); small or frictional ones on
    every row; an explicit override wins."""
    from compute.solvers import AUTO_QP_BODIES

    box, large = (0.0, 4.0, 0.0, 4.0), AUTO_QP_BODIES + 1
    assert compaction_parameters(box, 0.0, [1e-3], bodies=large)["solver"]["contact_screening"] == 0.1
    assert compaction_parameters(box, 0.0, [1e-3], bodies=AUTO_QP_BODIES)["solver"]["contact_screening"] == 0.0
    assert compaction_parameters(box, 0.2, [1e-3], bodies=large)["solver"]["contact_screening"] == 0.0
    forced = compaction_parameters(box, 0.0, [1e-3], {"solver.contact_screening": 0.0}, bodies=large)
    assert forced["solver"]["contact_screening"] == 0.0
