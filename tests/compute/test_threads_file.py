"""A run given more threads while it runs (OUT/threads, compute.threads.ThreadsFile) and the
dispatcher's share of freed cores (studies.dispatch.core_shares): the file is picked up after a
step, and the results do not depend on the thread count (the body-group kernels are per body)."""

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numba
import pytest

from compute import threads
from studies.dispatch import core_shares
from tests.deformable import scenes

# runs the scene on 1 thread, MIN_BODIES_PER_THREAD lowered to 1 so that its 4 soft bodies may use
# 2 threads; after step SWITCH (when given) writes OUT/threads = 2; prints the most threads a
# body-group kernel ran on
RUNNER = textwrap.dedent("""
    import sys, numba
    from compute import files, run as r, threads
    scene, out, switch = sys.argv[1], sys.argv[2], int(sys.argv[3])
    threads.MIN_BODIES_PER_THREAD = 1
    threads.configure(1)
    most, for_bodies, record = [0], threads.for_bodies, r.Run._record

    def counting(n):
        for_bodies(n)
        most[0] = max(most[0], numba.get_num_threads())

    def switching(self, *a):
        phi = record(self, *a)
        if self.state.step == switch:
            files.write_text(self.out / threads.THREADS_FILE, "2\\n")
        return phi

    threads.for_bodies, r.Run._record = counting, switching
    r.run(scene, out, log=lambda m: print(m, flush=True))
    print("most threads", most[0])
""")


def test_core_shares():
    assert core_shares(2, 1) == [2]
    assert core_shares(8, 3) == [3, 3, 2]  # the remainder to the first runs
    assert core_shares(2, 2) == [1, 1]
    assert core_shares(2, 3) == [1, 1, 1]  # never below one thread (least)
    assert core_shares(8, 3, least=4) == [4, 4, 4]
    assert core_shares(4, 0) == []


@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="needs a numba pool of 2 threads")
def test_threads_file_is_followed(tmp_path):
    before = threads.configured()
    try:
        threads.configure(1)
        follow = threads.ThreadsFile(tmp_path, log=(said := []).append)
        assert follow.poll() is None  # no file: nothing changes
        (tmp_path / "threads").write_text("2\n")
        assert follow.poll() == 2 and threads.configured() == 2
        assert follow.poll() is None  # unchanged file: one stat, no read
        (tmp_path / "threads").write_text("x")
        assert follow.poll() is None and threads.configured() == 2 and "ignored" in said[-1]
        threads.configure(1)
        (tmp_path / "threads").write_text(str(numba.config.NUMBA_NUM_THREADS + 5))
        assert follow.poll() == numba.config.NUMBA_NUM_THREADS  # capped to the pool
        (tmp_path / "threads").write_text("1")
        assert follow.poll() == 1 and threads.configured() == 1
    finally:
        threads.configure(before)


def _four_soft(folder: Path) -> Path:
    soft = [scenes.disk(30, "T3", centre=c, radius=1.0) for c in ((0.0, 0.0), (2.1, 0.0), (0.0, 2.1), (2.1, 2.1))]
    params = scenes.parameters((-1.1, 3.2, -1.1, 3.2), element="T3", friction=0.3, time_step=0.5,
                               contact_tolerance=1e-8, pressures=(0.01, 0.03), max_steps=12)
    params["output"].update(every_steps=4)
    return scenes.write(folder, params, soft=soft)


def _run(scene: Path, out: Path, switch: int) -> str:
    env = dict(os.environ, NUMBA_NUM_THREADS="2")
    done = subprocess.run([sys.executable, "-c", RUNNER, str(scene), str(out), str(switch)], env=env,
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    return done.stdout


def _files(out: Path) -> dict[str, bytes]:
    names = ["history.csv", "frames.csv", *(f"frames/{p.name}" for p in sorted((out / "frames").glob("*.vtu")))]
    return {n: (out / n).read_bytes() for n in names}


def test_switching_to_two_threads_mid_run_changes_no_result(tmp_path):
    scene = _four_soft(tmp_path / "scene")
    one = _run(scene, tmp_path / "one", switch=-1)
    two = _run(scene, tmp_path / "two", switch=3)
    assert "most threads 1" in one and "threads: 1 -> 2" not in one
    assert "threads: 1 -> 2" in two and "most threads 2" in two, two
    expected, got = _files(tmp_path / "one"), _files(tmp_path / "two")
    assert len(expected) > 3 and list(got) == list(expected)
    for name in expected:
        assert got[name] == expected[name], f"{name} differs between 1 thread and 1 then 2 threads"


@pytest.mark.skipif(len(os.sched_getaffinity(0)) < 2, reason="needs 2 cores to hand out")
def test_dispatcher_gives_the_freed_core_to_the_run_still_going(tmp_path, monkeypatch):
    from studies import dispatch as d
    from tests.compute.scenes import rigid_scene
    from tests.studies.test_mixture_dispatch import lattice_scene

    monkeypatch.setattr(d, "POLL", 0.2)
    long = rigid_scene(tmp_path / "long" / "scene", 60, 4, 10, 40)  # a few seconds
    short = lattice_scene(tmp_path / "short" / "scene")  # about one second
    said = []
    results = d.dispatch([d.RunSpec("long", long, tmp_path / "long" / "out"),
                          d.RunSpec("short", short, tmp_path / "short" / "out")],
                         n_workers=2, log=said.append, progress=False)
    assert [r.status for r in results] == ["complete", "complete"]
    assert any(m.startswith("long: 2 threads") for m in said), said
    assert "threads: 1 -> 2" in (tmp_path / "long" / "out" / "compute.log").read_text()
    assert not (tmp_path / "long" / "out" / "threads").exists()  # removed when the run ended


def test_configure_caps_the_blas_pool_numba_calls():
    """configure(1) in a fresh process leaves every loaded BLAS pool at one thread, the OpenBLAS
    behind numba's np.dot (scipy.linalg.cython_blas) included, whatever OPENBLAS_NUM_THREADS
    said: a run started by hand with --threads 1 has no busy-waiting BLAS thread."""
    code = textwrap.dedent("""
        import json, numba, numpy as np, threadpoolctl
        from compute import threads
        threads.configure(1)

        @numba.njit
        def dot(a, b):
            return np.dot(a, b)

        dot(np.ones(5000), np.ones(5000))
        print(json.dumps(sorted((i["filepath"], i["num_threads"]) for i in threadpoolctl.threadpool_info()
                                if i["user_api"] == "blas")))
    """)
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "2", "OMP_NUM_THREADS": "2"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env,
                         cwd=Path(__file__).resolve().parents[2]).stdout
    pools = json.loads(out)
    assert any("scipy_openblas" in path and "64" not in path for path, _ in pools), out  # numba's BLAS
    assert all(n == 1 for _, n in pools), out
