"""The mixture compaction study through its three scripts on a tiny sample (a few dozen disks, two
pressure stages): the files, P from contacts against P from walls, Z against the contacts listed in
the VTK frames (counted here independently), and a study killed midway finishing only what is
missing when started again."""

import csv
import fcntl
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from compute.output import read_frame_rows
from compute.scene import read_scene

ROOT = Path(__file__).resolve().parents[2]
STUDY = "studies.mixture_compaction"
TINY = ["--n", "16", "--mu", "0.2", "--jamming-mu", "0.2", "--seeds", "1", "--pressures", "0.001", "0.002"]


def script(name, workdir, *extra, **kw):
    return subprocess.run([sys.executable, "-m", f"{STUDY}.{name}", "--workdir", str(workdir), *extra],
                          cwd=ROOT, check=True, capture_output=True, text=True, **kw)


def independent_Z(contacts_vtu: Path, n_particles: int, threshold: float = 1e-9) -> float:
    """Z = (2 N_pp + N_pw) / N_p from the contact lines of a frame, one contact per pair of bodies
    carrying fn > threshold x the mean positive fn."""
    from meshio import vtu

    mesh = vtu.read(contacts_vtu)
    data = {k: np.concatenate([np.asarray(b).reshape(len(b), -1)[:, 0] for b in v]) for k, v in mesh.cell_data.items()
            if k in ("body_i", "body_j", "fn")}
    fn = data["fn"]
    active = fn > threshold * fn[fn > 0].mean()
    pairs = {tuple(sorted((int(i), int(j)))) for i, j in zip(data["body_i"][active], data["body_j"][active])}
    n_pp = sum(1 for i, j in pairs if i >= 0 and j >= 0)
    n_pw = sum(1 for i, j in pairs if i < 0 or j < 0)
    return (2 * n_pp + n_pw) / n_particles


def test_help():
    for name in ("pre", "compute", "post"):
        out = subprocess.run([sys.executable, "-m", f"{STUDY}.{name}", "--help"], cwd=ROOT, check=True, capture_output=True, text=True)
        assert "--workdir" in out.stdout
    assert "--scheduler" in subprocess.run([sys.executable, "-m", f"{STUDY}.compute", "--help"],
                                           cwd=ROOT, capture_output=True, text=True).stdout


def test_three_stages_end_to_end(tmp_path):
    w = tmp_path / "study"
    script("pre", w, *TINY, "--kappa", "0.5")
    script("compute", w, "--workers", "1")
    post = script("post", w)
    # b comes from the single-particle refinement table committed in the tree (same element, closest size)
    assert "refinement_fits.csv, row T3 x 92" in post.stdout
    study = json.loads((w / "study.json").read_text())
    (run,) = study["runs"]
    assert run["name"] == "k0.5_mu0.2_s1" and abs(run["kappa_actual"] - 0.5) < 0.1
    out = w / run["out"]
    for name in ("COMPLETE", "bodies.pvd", "contacts.pvd", "walls.pvd", "history.csv", "post/measures.csv"):
        assert (out / name).is_file(), name
    for name in ("table1.csv", "fits.csv", "errors.csv", "curves.csv", "summary.md", "fig1_views.png",
                 "fig2_compaction.png", "fig3_bulk_modulus.png", "fig4_coordination.png", "fig5_single_particle.png"):
        assert (w / "post" / name).is_file(), name
    rows = list(csv.DictReader(open(out / "post" / "measures.csv")))
    assert [float(r["pressure_applied"]) for r in rows] == [0.001, 0.002]
    assert all(r["equilibrated"] == "1" for r in rows)
    for r in rows:
        assert float(r["P"]) == pytest.approx(float(r["P_walls"]), rel=0.01)  # contacts against walls
        assert float(r["P_walls"]) == pytest.approx(float(r["pressure_applied"]), rel=0.01)
        Z = independent_Z(out / "frames" / f"contacts_{int(r['frame']):05d}.vtu", int(r["n_particles"]))
        assert float(r["Z"]) == pytest.approx(Z, abs=1e-12)
        assert 0.70 < float(r["phi"]) < 0.90
    table1 = list(csv.DictReader(open(w / "post" / "table1.csv")))
    # phi0, Z0 of the prepared sample (pre.py), the first stage's beside them
    assert table1[0]["phi0_from"] == "prepared" and "phi0, Z0: prepared" in post.stdout
    assert float(table1[0]["phi0"]) == pytest.approx(run["prepared"]["phi"])
    assert float(table1[0]["Z0"]) == pytest.approx(run["prepared"]["Z"])
    assert float(table1[0]["phi0_first_stage"]) == pytest.approx(float(rows[0]["phi"]))
    assert float(table1[0]["Z0_first_stage"]) == pytest.approx(float(rows[0]["Z"]))
    fits = list(csv.DictReader(open(w / "post" / "fits.csv")))
    assert {(f["law"], f["parameter"]) for f in fits} >= {("eq5", "phi_max"), ("single_particle (Eq. 2)", "b")}

    # the study carried to another machine without its frames: analysed from the kept measures
    import shutil

    shutil.rmtree(out / "frames")
    again = script("post", w)
    assert "fig1_views.png not redrawn" in again.stdout and (w / "post" / "fig1_views.png").is_file()
    assert list(csv.DictReader(open(w / "post" / "table1.csv"))) == table1
    assert list(csv.DictReader(open(out / "post" / "measures.csv"))) == rows


def _locked(path: Path) -> bool:
    with path.open("a") as f:
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            return True
        fcntl.flock(f, fcntl.LOCK_UN)
        return False


def _checkpointed_after_first_frame(out: Path) -> bool:
    frame, state = out / "frames" / "bodies_00000.vtu", out / "checkpoint" / "state.npz"
    try:
        return os.stat(state).st_mtime_ns >= os.stat(frame).st_mtime_ns
    except FileNotFoundError:
        return False


def test_killed_study_finishes_only_the_missing_runs(tmp_path):
    w = tmp_path / "study"
    script("pre", w, *TINY, "--kappa", "0.5", "1")
    first, second = w / "runs" / "k1_mu0.2_s1" / "out", w / "runs" / "k0.5_mu0.2_s1" / "out"  # heaviest first
    proc = subprocess.Popen([sys.executable, "-m", f"{STUDY}.compute", "--workdir", str(w), "--workers", "1"],
                            cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.time() + 240
        # kill once the first run is complete and the second has checkpointed its first stage: a
        # checkpoint no older than its first frame (the frame is written first; killed between
        # the two, the run would rightly start again)
        while not ((first / "COMPLETE").is_file() and _checkpointed_after_first_frame(second)):
            assert proc.poll() is None, "compute.py ended before it could be killed"
            assert time.time() < deadline
            time.sleep(0.05)
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    finally:
        if proc.poll() is None:
            proc.kill()
    assert not (second / "COMPLETE").is_file()
    # the run processes die with the study: the second run's lock is released
    deadline = time.time() + 30
    while _locked(second / ".lock"):
        assert time.time() < deadline, "a run process outlived the killed study"
        time.sleep(0.2)
    complete_mtime = os.stat(first / "COMPLETE").st_mtime_ns
    frame0_mtime = os.stat(second / "frames" / "bodies_00000.vtu").st_mtime_ns
    n_logged = len((w / "dispatch.jsonl").read_text().splitlines())

    script("compute", w, "--workers", "1")
    assert (second / "COMPLETE").is_file()
    assert os.stat(first / "COMPLETE").st_mtime_ns == complete_mtime  # not run again
    assert os.stat(second / "frames" / "bodies_00000.vtu").st_mtime_ns == frame0_mtime  # resumed, not restarted
    log = [json.loads(line) for line in (w / "dispatch.jsonl").read_text().splitlines()[n_logged:]]
    assert {e["name"]: e["status"] for e in log} == {"k1_mu0.2_s1": "skipped", "k0.5_mu0.2_s1": "complete"}
    assert next(e for e in log if e["name"] == "k0.5_mu0.2_s1")["resumed"]
    rows = read_frame_rows(second / "frames.csv")
    assert [r["stage"] for r in rows] == ["0", "1"] and all(r["equilibrated"] == "1" for r in rows)


def test_runs_added_to_a_study_keep_the_others(tmp_path):
    """pre --add adds runs to a study one at a time (a study run over several sessions): the
    runs already there keep their scenes and outputs, a jammed packing of the same (μ, seed) is
    reused, different settings are refused naming the field; compute --runs runs only those."""
    w = tmp_path / "study"
    script("pre", w, *TINY, "--kappa", "0.5")
    script("compute", w, "--workers", "1", "--runs", "k0.5_mu0.2_s1")
    first = w / "runs" / "k0.5_mu0.2_s1"
    stamps = {f: f.stat().st_mtime_ns for f in (first / "scene" / "scene.toml", first / "out" / "COMPLETE")}
    jam = w / "rigid" / "mu0.2_s1" / "scene" / "scene.toml"
    jam_stamp = jam.stat().st_mtime_ns

    bad = subprocess.run([sys.executable, "-m", f"{STUDY}.pre", "--workdir", str(w), *TINY[:-1], "0.003",
                          "--kappa", "1", "--add"], cwd=ROOT, capture_output=True, text=True)
    assert bad.returncode == 2 and "field 'pressures_over_E'" in bad.stderr and "study.json" in bad.stderr
    script("pre", w, *TINY, "--kappa", "0.5", "1", "--add")
    study = json.loads((w / "study.json").read_text())
    assert [r["name"] for r in study["runs"]] == ["k0.5_mu0.2_s1", "k1_mu0.2_s1"] and len(study["jamming"]) == 1
    assert {f: f.stat().st_mtime_ns for f in stamps} == stamps and jam.stat().st_mtime_ns == jam_stamp

    unknown = subprocess.run([sys.executable, "-m", f"{STUDY}.compute", "--workdir", str(w), "--runs", "k2_mu0_s1"],
                             cwd=ROOT, capture_output=True, text=True)
    assert unknown.returncode == 2 and "k2_mu0_s1 not in" in unknown.stderr
    script("compute", w, "--workers", "1", "--runs", "k1_mu0.2_s1")
    assert (w / "runs" / "k1_mu0.2_s1" / "out" / "COMPLETE").is_file()
    assert (first / "out" / "COMPLETE").stat().st_mtime_ns == stamps[first / "out" / "COMPLETE"]

    # a frictionless run compressed from the frictional packing (TINY's --jamming-mu): no new jamming,
    # the packing relaxed without friction with rigid disks (--relax rigid), the same soft disks moved
    script("pre", w, *TINY, "--kappa", "1", "--mu", "0", "--add")
    study = json.loads((w / "study.json").read_text())
    added = study["runs"][-1]
    assert (added["name"], added["mu"], added["jamming_mu"]) == ("k1_mu0_s1", 0.0, 0.2) and len(study["jamming"]) == 1
    assert [(r["mu"], r["from_mu"]) for r in study["relaxed"]] == [(0.0, 0.2)]
    frictional, frictionless = (read_scene(w / "runs" / name / "scene") for name in ("k1_mu0.2_s1", "k1_mu0_s1"))
    for a, b in zip(frictional.deformable, frictionless.deformable):
        np.testing.assert_allclose(a.points - a.points.mean(axis=0), b.points - b.points.mean(axis=0), atol=1e-9)
    assert frictional.friction.max() == 0.2 and frictionless.friction.max() == 0.0
