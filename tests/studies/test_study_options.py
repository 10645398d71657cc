"""Each study's three scripts with options other than the defaults (μ = 0, T3 and T6 elements,
one pressure stage), small: every stage exits 0 and writes its results. Why: the scripts read
what the earlier stages wrote, and a scene written with other options (a frictionless scene
omits its friction) broke the post script that read scene.toml without the schema."""

import csv
import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _stages(study: str, workdir: Path, pre: list[str], compute: list[str] = ()) -> None:
    for stage, extra in (("pre", pre), ("compute", compute), ("post", [])):
        done = subprocess.run([sys.executable, "-m", f"studies.{study}.{stage}", "--workdir", str(workdir), *extra],
                              cwd=ROOT, capture_output=True, text=True)
        assert done.returncode == 0, f"{study}.{stage}: {done.stderr[-2000:]}"


def _rows(path: Path) -> list[dict]:
    with open(path) as fh:
        return list(csv.DictReader(fh))


def test_rigid_jamming_frictionless_one_stage(tmp_path):
    _stages("rigid_jamming", tmp_path, ["--n", "30", "--mu", "0", "--pressures", "1"])
    (row,) = _rows(tmp_path / "out" / "post" / "measures.csv")
    assert row["equilibrated"] == "1"
    # the frictionless rattler rule (fewer than 3 contacts) read from the scene: every particle
    # left in Z_no_rattlers has at least 3 contacts, so its Z is at least 3
    assert float(row["Z_no_rattlers"]) >= 3.0


def test_single_particle_t3(tmp_path):
    _stages("single_particle", tmp_path, ["--element-type", "T3", "--elements", "40", "--stages", "3",
                                          "--p-min", "0.01", "--p-max", "0.1"])
    fit = json.loads((tmp_path / "out" / "post" / "fit.json").read_text())
    assert fit["n_points"] == 3
    phi = [float(r["phi"]) for r in _rows(tmp_path / "out" / "post" / "measures.csv")]
    assert phi == sorted(phi) and 0.7 < phi[0] and phi[-1] < 1.0  # compacted as the pressure grows


def test_mixture_t6_frictionless_one_stage(tmp_path):
    _stages("mixture_compaction", tmp_path, ["--n", "12", "--mu", "0", "--kappa", "1", "--element", "T6",
                                              "--elements", "24", "--pressures", "0.001", "--preparation",
                                              "per-friction"], ["--workers", "1"])  # frictionless throughout
    (table1,) = _rows(tmp_path / "post" / "table1.csv")
    assert (float(table1["kappa"]), float(table1["mu"])) == (1.0, 0.0)
    assert 0.7 < float(table1["phi0_first_stage"]) < 0.95
    # the prepared sample, before any load (12 disks: mostly wall layer), is the looser
    assert 0.6 < float(table1["phi0"]) < float(table1["phi0_first_stage"])
