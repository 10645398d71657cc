"""The checkout a benchmark measures (benchmarks run from a git worktree of another commit too)."""

from __future__ import annotations

import subprocess


def commit(cwd=None) -> str:
    """Short hash of HEAD of the git checkout at ``cwd`` (the current directory by default)."""
    return subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=cwd, capture_output=True,
                          text=True, check=True).stdout.strip()
