"""Fixtures of the post tests: synthetic output folders (see synthetic.py)."""

from __future__ import annotations

import pytest
from tests.post.synthetic import write_square_lattice


@pytest.fixture
def lattice(tmp_path):
    """4 x 4 touching rigid disks (d = 1) at P = 0.01 and 0.1."""
    return write_square_lattice(tmp_path / "lattice")


@pytest.fixture
def mixed_lattice(tmp_path):
    """The lattice with disks 5 and 6 deformable (T6 fans) and a rattler in a hole, compressed in
    four frames (spacing 1 to 0.97 d), the second not equilibrated."""
    return write_square_lattice(tmp_path / "mixed", pressures=(0.01, 0.02, 0.05, 0.1),
                                spacings=(1.0, 0.99, 0.98, 0.97), equilibrated=(True, False, True, True),
                                deformable=(5, 6), rattler=True)
