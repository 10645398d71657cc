"""A study's stage run as a file, ``python studies/X/stage.py``, from any folder.

Python puts a script's own folder first on ``sys.path``. A study's folder holds ``pre.py``,
``compute.py`` and ``post.py``, which would then shadow the toolkit's packages of the same names
(``from pre.jamming import ...`` in studies/X/pre.py would import the script itself), and the
repository root is on the path only when it is the working folder or the toolkit is installed.
So every stage script begins with::

    if not __package__:  # run as a file (python studies/X/stage.py): studies/entry.py
        import pathlib, sys; sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2]))
        from studies.entry import run_as_file; run_as_file(__file__)

the repository root first (the one step this module cannot take for it: it is not importable
before), then :func:`run_as_file`. Run as a module (``python -m studies.X.stage``) or through a
console command of pyproject.toml, ``__package__`` is set and nothing of this happens.
"""

from __future__ import annotations

import sys
from pathlib import Path


def _resolved(entry: str) -> Path:
    return Path(entry or ".").resolve()


def run_as_file(script: str) -> None:
    """``sys.path`` for the stage script ``script`` (its ``__file__``) run as a file: the
    repository holding it first, and its own folder nowhere."""
    folder = Path(script).resolve().parent
    root = folder.parents[1]  # studies/X/stage.py
    sys.path[:] = [str(root)] + [p for p in sys.path if _resolved(p) not in (folder, root)]
