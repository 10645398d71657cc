"""A run says once that numba is compiling when it first does, and nothing when every kernel
comes from numba's cache (compute.compiling, shown by compute.progress.RunProgress)."""

import io
import os
import subprocess
import sys
import textwrap

import pytest

from compute.compiling import MESSAGE, CompileNotice
from compute.progress import Display, RunProgress
from tests.compute.scenes import small_rigid_scene


def test_said_once_at_the_first_compilation_and_not_after_stop():
    import numba

    said = []
    with CompileNotice(said.append) as notice:
        assert not notice.said
        numba.njit(lambda x: x + 1)(1)  # a new function: compiled, never cached
        numba.njit(lambda x: x + 2)(1)
    numba.njit(lambda x: x + 3)(1)
    assert said == [MESSAGE] and notice.said


def test_run_progress_shows_it_until_the_run_finishes(tmp_path):
    import numba

    stream = io.StringIO()
    progress = RunProgress(tmp_path, 1, Display(1, "compute", stream=stream, interactive=False, interval=0.0))
    numba.njit(lambda x: x * 2)(1)
    progress.finish("complete")
    numba.njit(lambda x: x * 3)(1)
    assert stream.getvalue().splitlines() == [f"compute: {MESSAGE}"]


def _cached_kernel_run(folder, cache) -> str:
    """stderr of a process that calls a numba kernel with cache=True (a module of ``folder``)
    during a RunProgress, with NUMBA_CACHE_DIR = ``cache``."""
    (folder / "kernel.py").write_text(textwrap.dedent("""
        import numba

        @numba.njit(cache=True)
        def twice(x):
            return 2 * x
        """))
    script = textwrap.dedent(f"""
        import sys
        from pathlib import Path
        sys.path.insert(0, {str(folder)!r})
        from compute.progress import Display, RunProgress
        progress = RunProgress(Path({str(folder)!r}), 1, Display(1, "compute", interactive=False, interval=0.0))
        import kernel
        assert kernel.twice(21) == 42
        progress.finish("complete")
        """)
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache)}
    r = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    return r.stderr


def test_a_cached_kernel_is_announced_when_compiled_only(tmp_path):
    cache = tmp_path / "numba_cache"
    assert MESSAGE in _cached_kernel_run(tmp_path, cache)  # a fresh cache: compiled
    assert any(cache.rglob("*.nbi"))
    assert MESSAGE not in _cached_kernel_run(tmp_path, cache)  # loaded from the cache


@pytest.mark.slow
def test_first_compute_with_a_fresh_cache_says_it_compiles_and_the_next_does_not(tmp_path):
    """The toolkit's own kernels: ``python -m compute`` with an empty NUMBA_CACHE_DIR compiles
    them (minutes on a loaded machine), then a second run loads them all."""
    scene = small_rigid_scene(tmp_path / "scene")
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba_cache")}

    def compute(out):
        r = subprocess.run([sys.executable, "-m", "compute", str(scene), "--out", str(tmp_path / out)], env=env,
                           capture_output=True, text=True, timeout=1800)
        assert r.returncode == 0, r.stderr
        return r.stderr

    first = compute("cold")
    assert first.count(MESSAGE) == 1
    assert MESSAGE not in compute("warm")
