"""studies.mixture_compaction.view: runs of several study folders gathered into one study for
post.py, on hand-written study folders (no compute): paths that lead back to the runs, each
run's scene options, run times from the folders' dispatch logs, and the refusals."""

import json
from pathlib import Path

import pytest

from studies.dispatch import run_times
from studies.mixture_compaction.view import view

SETTINGS = {"study": "mixture_compaction", "n": 1500, "element": "T3", "elements": 92, "volumetric": "standard",
            "pressures_over_E": [0.001, 1.0], "young": 1.0, "poisson": 0.495}


def study_folder(root: Path, name: str, runs: list[str], overrides=None, **changed) -> Path:
    folder = root / name
    folder.mkdir(parents=True)
    entries = [{"name": r, "kappa": 0.5, "mu": 0.0, "seed": 1, "scene": f"runs/{r}/scene", "out": f"runs/{r}/out"}
               for r in runs]
    for r in runs:
        (folder / "runs" / r / "out").mkdir(parents=True)
    study = {**SETTINGS, **changed, "overrides": overrides or {}, "runs": entries, "pre_seconds": 10.0}
    (folder / "study.json").write_text(json.dumps(study))
    log = [{"name": r, "status": s, "wall_time": t} for r in runs for s, t in (("killed", 100.0), ("complete", 20.0))]
    (folder / "dispatch.jsonl").write_text("".join(json.dumps(e) + "\n" for e in log))
    return folder


def test_a_view_leads_back_to_the_runs_with_their_options_and_times(tmp_path):
    a = study_folder(tmp_path, "nodes", ["k0.2_mu0.2_s1", "k1_mu0_s1"])
    b = study_folder(tmp_path, "segments", ["k0.2_mu0_s1", "k0.2_mu0.2_s1"],
                     overrides={"solver.rigid_soft_rows": "nodes_and_segments"})
    w = tmp_path / "results" / "view"
    study = view(w, [f"{a}/k0.2_mu0.2_s1", f"{a}/k1_mu0_s1", f"{b}/k0.2_mu0_s1"])
    assert json.loads((w / "study.json").read_text()) == study
    assert [r["name"] for r in study["runs"]] == ["k0.2_mu0.2_s1", "k1_mu0_s1", "k0.2_mu0_s1"]
    expected = [a / "runs/k0.2_mu0.2_s1/out", a / "runs/k1_mu0_s1/out", b / "runs/k0.2_mu0_s1/out"]
    assert [(w / r["out"]).resolve() for r in study["runs"]] == [p.resolve() for p in expected]
    assert [r["overrides"] for r in study["runs"]] == [{}, {}, {"solver.rigid_soft_rows": "nodes_and_segments"}]
    assert {k: study[k] for k in SETTINGS} == SETTINGS and study["pre_seconds"] == 20.0
    # run times: the dispatches of the chosen runs only (b's k0.2_mu0.2_s1 is not in the view)
    assert run_times(w / "dispatch.jsonl") == {"k0.2_mu0.2_s1": 120.0, "k1_mu0_s1": 120.0, "k0.2_mu0_s1": 120.0}


@pytest.mark.parametrize("case, message", [
    ("missing folder", "study.json: not found"),
    ("missing run", "has no run named 'k9_mu0_s1'"),
    ("same name twice", "already in the view"),
    ("other settings", "field 'element' is 'T6', expected 'T3'"),
])
def test_a_view_refuses_what_cannot_be_analysed_together(tmp_path, case, message):
    a = study_folder(tmp_path, "a", ["k0.2_mu0.2_s1"])
    b = study_folder(tmp_path, "b", ["k0.2_mu0.2_s1", "k1_mu0_s1"], **({"element": "T6"} if case == "other settings" else {}))
    runs = {"missing folder": [f"{tmp_path}/none/k0.2_mu0.2_s1"], "missing run": [f"{a}/k9_mu0_s1"],
            "same name twice": [f"{a}/k0.2_mu0.2_s1", f"{b}/k0.2_mu0.2_s1"],
            "other settings": [f"{a}/k0.2_mu0.2_s1", f"{b}/k1_mu0_s1"]}[case]
    with pytest.raises(ValueError, match=message):
        view(tmp_path / "view", runs)
