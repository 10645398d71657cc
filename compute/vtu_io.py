"""Validated reading of the VTU files the stages exchange (bodies files, frames).

Every problem is an error of the caller's type (a :class:`compute.errors.InputError`: SceneError
for a scene, post's OutputError for an output folder) naming the file, the field and what was
expected.
"""

from __future__ import annotations

from pathlib import Path
from xml.etree import ElementTree

import numpy as np

from compute import files
from compute.errors import InputError


def read_vtu(path: str | Path, error: type[InputError], allow_empty: bool = False):
    """The meshio mesh of ``path``; None for a piece with no cells when ``allow_empty``."""
    from meshio import vtu  # not meshio.read, which prints and calls sys.exit on a corrupt file

    path = Path(path)
    if not files.is_file(path, error):
        raise error(path, "<file>", "an existing VTU file")
    try:
        return vtu.read(path)
    except Exception as exc:  # meshio raises many types on truncated or corrupt XML
        if allow_empty and _has_no_cells(path):
            return None
        raise error(path, "<file>", "a complete VTU file readable by meshio", f"{type(exc).__name__}: {exc}") from None


def _has_no_cells(path: Path) -> bool:
    """A complete VTU document (parsed to its end: a file cut short is not empty, it is cut)
    whose piece has no cells."""
    try:
        piece = ElementTree.parse(path).getroot().find("./UnstructuredGrid/Piece")
    except ElementTree.ParseError:
        return False
    return piece is not None and piece.get("NumberOfCells", "").strip() == "0"


def cell_field(mesh, path: Path, name: str, error: type[InputError], components: int = 1,
               integer: bool = False) -> np.ndarray:
    """Cell field ``name`` concatenated over the cell blocks: shape (n_cells,) for
    ``components == 1``, else (n_cells, components) taken from 2 or 3 stored components; finite;
    ``integer``: integer values below 2^31 in magnitude, returned as int64."""
    if name not in mesh.cell_data:
        raise error(path, f"cell_data.{name}", "a cell array on every cell block (missing)")
    blocks = mesh.cell_data[name]
    if len(blocks) != len(mesh.cells) or any(len(b) != len(c.data) for b, c in zip(blocks, mesh.cells)):
        raise error(path, f"cell_data.{name}", "one value per cell on every cell block")
    values = np.concatenate([np.asarray(b, dtype=float).reshape(len(b), -1) for b in blocks])
    stored = values.shape[1]
    if (components == 1 and stored != 1) or (components > 1 and stored not in (components, 3)):
        expected = "a scalar" if components == 1 else f"{components} or 3 components"
        raise error(path, f"cell_data.{name}", expected, f"{stored} components")
    if not np.all(np.isfinite(values)):
        raise error(path, f"cell_data.{name}", "finite values")
    values = values[:, 0] if components == 1 else values[:, :components]
    if integer:
        if not np.all((values == np.round(values)) & (np.abs(values) < 2**31)):
            raise error(path, f"cell_data.{name}", "integers (below 2^31 in magnitude)")
        return values.astype(np.int64)
    return values
