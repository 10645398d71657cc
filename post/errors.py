"""Errors raised by the post-processing stage."""

from __future__ import annotations

from compute.errors import InputError


class OutputError(InputError):
    """An output folder is missing, malformed or inconsistent (docs/FORMATS.md); the message
    names the file, the field and what was expected (the toolkit's one input-error model)."""


class RenderError(RuntimeError):
    """No usable off-screen OpenGL backend for VTK rendering (see post.render)."""
