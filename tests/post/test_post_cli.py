"""``python -m post`` end to end on a synthetic output folder."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from post.__main__ import main
from post.table import COLUMNS, measure_output, read_measures

REQUIRED = ("frame", "time", "pressure_applied", "equilibrated", "phi", "P", "P_walls", "q", "Z", "Z_no_rattlers",
            "Z_bulk", "n_contacts", "n_rattlers", "n_particles")
ROOT = Path(__file__).resolve().parents[2]


def test_cli_end_to_end(mixed_lattice):
    done = subprocess.run([sys.executable, "-m", "post", str(mixed_lattice), "--friction", "0"], cwd=ROOT,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    target = mixed_lattice / "post"
    for name in ("measures.csv", "force_chains.png", "phi_Z_vs_P.png"):
        assert (target / name).stat().st_size > 0
    table = read_measures(target / "measures.csv")
    assert set(REQUIRED) <= set(table.dtype.names) and table.dtype.names == COLUMNS
    assert table["frame"].tolist() == [0, 1, 2, 3]
    assert table["equilibrated"].tolist() == [1, 0, 1, 1]
    rows = measure_output(mixed_lattice, min_contacts=3)
    for name in ("phi", "P", "P_walls", "Z", "Z_no_rattlers", "K"):   # the CSV round-trips exactly
        np.testing.assert_array_equal(table[name], [row[name] for row in rows])


def test_cli_min_contacts_changes_the_rattlers(lattice):
    assert main([str(lattice), "--min-contacts", "5"]) == 0
    table = read_measures(lattice / "post" / "measures.csv")
    assert table["n_rattlers"].tolist() == [16, 16] and np.isnan(table["Z_no_rattlers"]).all()


def test_cli_reports_bad_output(tmp_path, capsys):
    assert main([str(tmp_path)]) == 2
    assert "frames.csv" in capsys.readouterr().err


def test_cli_rejects_both_rattler_options(lattice):
    with pytest.raises(SystemExit):
        main([str(lattice), "--friction", "0.2", "--min-contacts", "3"])
