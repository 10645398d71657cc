"""post.compaction on synthetic studies generated from the paper's laws with known parameters."""

from __future__ import annotations

import json

import numpy as np
import pytest

from post import compaction, models
from post.compaction import Reference, SingleParticleLaw

B, XI, ALPHA = 0.14, 5.1, 0.5
PHI_MAX = {0.5: 0.93, 1.0: 0.97}  # Eq. 5's phi_max per kappa
PHI0, Z0 = 0.811, 3.6
LAW = SingleParticleLaw(B, 0.99, "synthetic")


def _rows(kappa: float, seed: int) -> list[dict]:
    """The measures rows (post.table columns used by the analysis) of a run following Eq. 5 and the
    coordination law exactly, with phi0 shifted a little per seed."""
    phi0 = PHI0 + 0.002 * (seed - 1)
    phi = np.linspace(phi0, phi0 + 0.1, 9)
    P = np.concatenate([[1e-6], models.eq5_pressure(phi[1:], PHI_MAX[kappa], B, XI, ALPHA, Z0, phi0)])
    Z = models.coordination_law(phi, XI, ALPHA, phi0, Z0)
    K = phi * np.gradient(P, phi)
    return [{"stage": k, "equilibrated": True, "phi": f, "P": p, "P_walls": p, "pressure_applied": p, "Z": z, "K": kk,
             "Z_no_rattlers": z + 0.1 * seed} for k, (f, p, z, kk) in enumerate(zip(phi, P, Z, K))]


@pytest.fixture(scope="module")
def study():
    runs = [{"name": f"k{k}_s{s}", "kappa": k, "mu": 0.2, "seed": s, "out": f"runs/k{k}_s{s}/out"}
            for k in PHI_MAX for s in (1, 2)]
    return {"runs": runs, "n": 30, "element": "T3", "elements": 92, "pressures_over_E": [1e-3, 0.1]}


@pytest.fixture(scope="module")
def result(study):
    tables = {r["name"]: _rows(r["kappa"], r["seed"]) for r in study["runs"]}
    return compaction.analyse(study, tables, LAW, "Z", "all", (XI, ALPHA))


def test_laws_recovered(result):
    glob = result.coordination_all
    assert glob.params["xi"] == pytest.approx(XI, rel=1e-6) and glob.params["alpha"] == pytest.approx(ALPHA, rel=1e-6)
    for (kappa, mu), g in result.groups.items():
        assert g.seeds == [1, 2] and g.phi0 == pytest.approx(PHI0 + 0.001)
        assert g.phi0_std == pytest.approx(0.002 / np.sqrt(2))
        # Eq. 5 pooled over two seeds of different phi0 uses the mean phi0: phi_max close, not exact;
        # each seed alone recovers it exactly, so the seed scatter of phi_max is ~0
        assert g.eq5.params["phi_max"] == pytest.approx(PHI_MAX[kappa], abs=5e-3)
        assert g.seed_std["eq5_phi_max"] == pytest.approx(0.0, abs=1e-8)


def test_seed_scatter_of_every_fitted_number(study):
    """Seeds whose Z follow the coordination law with ξ = 5.0 and 5.4: each seed fitted alone gives
    its own ξ exactly, so the scatter is that of the two values, per group and over all runs; the
    seeds' φ(P) follow one Eq. 5, so φ_max and the law errors scatter by nothing."""
    xis = {1: 5.0, 2: 5.4}
    tables = {}
    for r in study["runs"]:
        rows = _rows(r["kappa"], r["seed"])
        phi0 = rows[0]["phi"]
        for row in rows:
            row["Z"] = float(models.coordination_law(np.array([row["phi"]]), xis[r["seed"]], ALPHA, phi0, Z0)[0])
        tables[r["name"]] = rows
    result = compaction.analyse(study, tables, LAW, "Z", "all", (XI, ALPHA))
    expected = 0.4 / np.sqrt(2)
    assert result.coordination_all_seed_std["xi"] == pytest.approx(expected, rel=1e-6)
    assert result.coordination_all_seed_std["alpha"] == pytest.approx(0.0, abs=1e-6)
    for g in result.groups.values():
        assert g.seed_std["xi"] == pytest.approx(expected, rel=1e-6)
        assert g.seed_std["alpha"] == pytest.approx(0.0, abs=1e-6)
        assert g.seed_std["platzer_phi_max"] >= 0.0 and np.isfinite(g.seed_std["platzer_P0"])
    rows = {(r["kappa"], r["parameter"]): r["value"] for r in result.fit_rows if r["law"] == "per seed"}
    assert rows[("all", "xi std")] == pytest.approx(expected, rel=1e-6) and (0.5, "eq5_phi_rms std") in rows
    text = compaction.summary_markdown(study, result, Reference({}, {}, XI, ALPHA, B))
    assert "| ξ | 5.2 ± 0.3 |" in text  # pooled ξ (the two seeds' 5.0 and 5.4) ± their scatter 0.28
    # a (κ, μ) with one seed only: a seed's fit over all runs would mix groups, so no scatter there
    partial = {**study, "runs": [r for r in study["runs"] if not (r["kappa"] == 1.0 and r["seed"] == 2)]}
    uneven = compaction.analyse(partial, {r["name"]: tables[r["name"]] for r in partial["runs"]}, LAW, "Z", "all",
                                (XI, ALPHA))
    assert np.isnan(uneven.coordination_all_seed_std["xi"])
    assert uneven.groups[(0.5, 0.2)].seed_std["xi"] == pytest.approx(expected, rel=1e-6)


def test_table1_and_fit_rows(result):
    rows = {(r["kappa"], r["mu"]): r for r in result.table1({0.2: {0.5: 0.811}}, {0.2: {0.5: 3.7}})}
    assert rows[(0.5, 0.2)]["phi0_paper"] == 0.811 and rows[(1.0, 0.2)]["phi0_paper"] == ""
    assert rows[(0.5, 0.2)]["n_seeds"] == 2 and rows[(0.5, 0.2)]["n_points"] == 18
    # Z0 without rattlers is its own column, averaged over the seeds: Z0 + 0.1 and Z0 + 0.2 here
    assert rows[(0.5, 0.2)]["Z0_no_rattlers"] == pytest.approx(Z0 + 0.15)
    assert rows[(0.5, 0.2)]["Z0_no_rattlers_std"] == pytest.approx(0.1 / np.sqrt(2))
    laws = {(r["law"], r["kappa"], r["parameter"]) for r in result.fit_rows}
    assert ("eq5", 0.5, "phi_max") in laws and ("coordination", "all", "xi") in laws
    assert ("single_particle (Eq. 2)", "all", "b") in laws


def test_phi0_of_the_prepared_sample_or_of_the_first_stage(study):
    """φ₀, Z₀ of the runs' prepared sample (study.json "prepared") by default when every run has
    them, else of the first equilibrated stage; table1 has both readings whichever the fits use."""
    tables = {r["name"]: _rows(r["kappa"], r["seed"]) for r in study["runs"]}
    ready = {"phi": PHI0 - 0.004, "Z": Z0 - 0.5, "Z_no_rattlers": Z0 - 0.2}
    prepared = {**study, "runs": [{**r, "prepared": ready} for r in study["runs"]]}
    result = compaction.analyse(prepared, tables, LAW)
    assert result.phi0_from == "prepared"
    for g in result.groups.values():
        assert (g.phi0, g.Z0, g.Z0_no_rattlers) == (PHI0 - 0.004, Z0 - 0.5, Z0 - 0.2) and g.phi0_std == 0.0
        assert g.phi0_first_stage == pytest.approx(PHI0 + 0.001) and g.Z0_first_stage == pytest.approx(Z0)
        assert all(p["phi0"] == PHI0 - 0.004 for p in result.points if p["kappa"] == g.kappa)
    row = result.table1()[0]
    assert row["phi0_from"] == "prepared" and row["phi0_prepared"] == PHI0 - 0.004 and row["Z0_prepared"] == Z0 - 0.5
    assert row["phi0_first_stage"] == pytest.approx(PHI0 + 0.001)
    text = compaction.summary_markdown(prepared, result, Reference({}, {}, XI, ALPHA, B))
    assert "φ₀, Z₀: the prepared sample's" in text and "| 0.5 | 0.2 | 2 | 0.8070 (–) | 3.10 (–)" in text

    first = compaction.analyse(prepared, tables, LAW, phi0="first-stage")
    g = first.groups[(0.5, 0.2)]
    assert first.phi0_from == "first-stage" and g.phi0 == pytest.approx(PHI0 + 0.001) and g.phi0_prepared == PHI0 - 0.004
    # a study with a run without prepared values (written before they were): the first stage
    partial = {**prepared, "runs": [study["runs"][0], *prepared["runs"][1:]]}
    assert compaction.analyse(partial, tables, LAW).phi0_from == "first-stage"
    with pytest.raises(ValueError, match=f"'prepared'.*{study['runs'][0]['name']}"):
        compaction.analyse(partial, tables, LAW, phi0="prepared")


def test_inverse_and_errors_of_an_exact_law():
    phi = np.linspace(0.82, 0.9, 7)
    model = lambda x: models.platzer_pressure(x, 0.05, 0.95, PHI0)  # noqa: E731
    P = model(phi)
    np.testing.assert_allclose(compaction.phi_of_pressure(model, P, PHI0, 0.95), phi, atol=1e-12)
    e = compaction.law_errors(model, phi, P, PHI0, 0.95)
    assert e["phi_max_abs"] < 1e-12 and e["P_max_rel"] < 1e-12
    e = compaction.law_errors(model, phi, 1.1 * P, PHI0, 0.95)  # 10 % more pressure than the law
    assert e["P_max_rel"] == pytest.approx(1 - 1 / 1.1, abs=1e-12)  # |P_law / P - 1|


def test_law_from_a_json_and_from_a_table(tmp_path):
    (tmp_path / "fit.json").write_text(json.dumps({"b": 0.2, "phi_p_max": 0.98, "phi_range": [0.79, 0.97]}))
    law = compaction.law_from_file(tmp_path / "fit.json", "T3", 92)
    assert (law.b, law.phi_p_max, law.paper_default) == (0.2, 0.98, False)
    table = tmp_path / "fits.csv"
    table.write_text("element,elements,boundary_segments,b,phi_p_max,phi_min,phi_max\n"
                     "T3,30,,0.3,0.97,0.79,0.96\nT3,92,,0.19,0.985,0.79,0.98\nT6,92,,0.15,0.99,0.79,0.98\n")
    law = compaction.law_from_file(table, "T3", 100)
    assert (law.b, law.phi_p_max) == (0.19, 0.985)


def test_summary_names_the_numbers_and_the_unfinished_runs(study, result):
    text = compaction.summary_markdown(study, result, Reference({}, {}, XI, ALPHA, B), {"k0.5_s1": 12.0},
                                       {"k0.5_s1": "complete", "k1.0_s2": "incomplete"}, {"k1.0_s2": "stage 3"})
    # φ₀ = 0.812 ± 0.0014 (two seeds 0.002 apart): the scatter to two digits (a leading 1), φ₀ at its place
    assert "| 0.5 | 0.2 | 2 | 0.8120 ± 0.0014" in text
    assert "| ξ | 5.1 | 5.1 |" in text and "| 12 |" in text and "- k1.0_s2: incomplete (stage 3)" in text
    assert "runs: 12 s; pre: – s." in text  # no pre time recorded
    text = compaction.summary_markdown({**study, "pre_seconds": 915.9000000000001}, result,
                                       Reference({}, {}, XI, ALPHA, B), {"k0.5_s1": 12.0})
    assert "pre: 916 s." in text


def test_measure_runs_says_why_a_run_is_left_out(tmp_path):
    """A run without output, one whose frames.csv has no frame yet and one with a broken
    frames.csv are left out, each with its own reason; a run with frames is measured."""
    from post.compaction import measure_runs
    from tests.post.synthetic import write_square_lattice

    write_square_lattice(tmp_path / "good")
    (tmp_path / "early").mkdir()
    (tmp_path / "early" / "frames.csv").write_text((tmp_path / "good" / "frames.csv").read_text().splitlines()[0] + "\n")
    (tmp_path / "broken").mkdir()
    (tmp_path / "broken" / "frames.csv").write_text("frame,time\n0,zero\n")
    runs = [{"name": name, "mu": 0.2, "out": name} for name in ("good", "missing", "early", "broken")]
    said = []
    tables = measure_runs(tmp_path, {"runs": runs}, log=said.append)
    assert list(tables) == ["good"] and len(tables["good"]) == 2
    assert any("missing: no output yet" in line for line in said)
    assert any("early: no frame yet" in line for line in said)
    assert any("broken: unreadable output" in line for line in said)
