"""The repository holds code and small results, not simulation state: no tracked file above 1 MB
and all tracked files together under 10 MB (scenes, checkpoints and frames are made again by
the commands in the studies' READMEs, studies/mixture_compaction/results/README.md)."""

import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FILE_LIMIT = 1_000_000  # bytes
TOTAL_LIMIT = 10_000_000  # bytes


def tracked_sizes() -> dict[str, int]:
    """Size in bytes of every file git tracks in the working tree (deleted ones left out)."""
    if shutil.which("git") is None or not (ROOT / ".git").exists():
        pytest.skip("not a git checkout")
    out = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, check=True).stdout
    paths = [p for p in out.decode().split("\0") if p]
    return {p: (ROOT / p).stat().st_size for p in paths if (ROOT / p).is_file()}


def test_no_tracked_file_above_limit():
    big = {p: s for p, s in tracked_sizes().items() if s > FILE_LIMIT}
    assert not big, "tracked files above 1 MB (keep them out of git, or compress them): " + ", ".join(
        f"{p} ({s / 1e6:.1f} MB)" for p, s in sorted(big.items(), key=lambda x: -x[1]))


def test_tracked_total_below_limit():
    sizes = tracked_sizes()
    total = sum(sizes.values())
    largest = sorted(sizes.items(), key=lambda x: -x[1])[:5]
    assert total < TOTAL_LIMIT, f"tracked files total {total / 1e6:.1f} MB; largest: " + ", ".join(
        f"{p} ({s / 1e6:.2f} MB)" for p, s in largest)
