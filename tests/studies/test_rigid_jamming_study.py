"""The rigid jamming study through its three scripts, on a small sample: files, equilibrium
stress check (contacts against walls), and no penetration drift."""

import csv
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]


def _opens_in_pyvista(study: Path, n_frames: int) -> None:
    """The prepared scene and every .pvd series open with pyvista (ParaView's reader, VTK)."""
    import pyvista

    scene = pyvista.read(study / "scene" / "bodies.vtu")
    assert scene.n_cells == 60 and "radius" in scene.cell_data
    for series in ("bodies", "contacts", "walls"):
        reader = pyvista.get_reader(str(study / "out" / f"{series}.pvd"))
        assert len(reader.time_values) == n_frames
        reader.set_active_time_point(n_frames - 1)
        assert reader.read()[0].n_cells > 0


@pytest.mark.parametrize("mu", [0.2])
def test_three_stages_end_to_end(tmp_path, mu):
    w = str(tmp_path / "study")
    for script, extra in (("pre", ["--n", "60", "--mu", str(mu), "--seed", "2"]), ("compute", []),
                          ("post", [])):
        subprocess.run([sys.executable, "-m", f"studies.rigid_jamming.{script}", "--workdir", w, *extra], cwd=ROOT, check=True,
                       capture_output=True)
    out = tmp_path / "study" / "out"
    for name in ("bodies.pvd", "contacts.pvd", "walls.pvd", "history.csv", "post/measures.csv",
                 "post/force_chains.png", "post/phi_Z_vs_P.png"):
        assert (out / name).is_file(), name
    _opens_in_pyvista(tmp_path / "study", n_frames=3)
    rows = list(csv.DictReader(open(out / "post" / "measures.csv")))
    assert len(rows) == 3 and all(r["equilibrated"] == "1" for r in rows)
    for r in rows:
        assert float(r["P"]) == pytest.approx(float(r["P_walls"]), rel=0.01)  # stress from contacts = walls
        assert float(r["P_walls"]) == pytest.approx(float(r["pressure_applied"]), rel=0.01)
        assert 0.70 < float(r["phi"]) < 0.86
    # no drift: penetration below 1e-3 <d> at every step of the preparation and of the run
    for hist in (out / "history.csv", tmp_path / "study" / "jamming" / "out" / "history.csv"):
        pen = np.genfromtxt(hist, delimiter=",", names=True)["max_penetration"]
        assert pen.max() < 1e-3 * 1.0  # <d> = 1 in the study's units


def test_frictionless_jammed_packing_is_isostatic(tmp_path):
    """Frictionless disks jam isostatic: as many contacts (walls included) as force-balance
    equations, 2 N' + 4 wall equations less 2 global translations, i.e. Z_constraints = 4 + 4/N'
    over the N' non-rattlers (isostaticity of frictionless jamming: an independent count)."""
    from post.table import measure_output
    from pre.jamming import jammed_rigid_scene

    jammed_rigid_scene(tmp_path, 50, 0.0, 5, [1.0], log=lambda m: None)
    row = measure_output(tmp_path / "jamming" / "out", min_contacts=3)[-1]
    n = row["n_particles"] - row["n_rattlers"]
    assert row["equilibrated"] == 1
    assert row["Z_constraints"] == pytest.approx(4 + 4 / n, abs=0.1)
    assert row["P"] == pytest.approx(row["P_walls"], rel=0.01)
    assert 0.75 < row["phi"] < 0.85
