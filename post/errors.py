"""Errors raised by the post-processing stage."""

from __future__ import annotations

from pathlib import Path


class OutputError(ValueError):
    """An output folder is missing, malformed or inconsistent (docs/FORMATS.md).

    The message names the file, the field and what was expected.
    """

    def __init__(self, file: str | Path, field: str, expected: str, got: object = None):
        self.file, self.field, self.expected = str(file), field, expected
        message = f"{file}: field '{field}': expected {expected}"
        if got is not None:
            message += f", got {got!r}"
        super().__init__(message)


class RenderError(RuntimeError):
    """No usable off-screen OpenGL backend for VTK rendering (see post.render)."""
