"""Dispatching independent runs (scene folder -> output folder) with Dask distributed.

A study is many independent runs (κ × μ × seeds × ...). :func:`dispatch` sends them to a Dask
cluster: a ``LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=None)`` on this
machine by default, or the scheduler at a given address (workers there need this toolkit
installed and the run folders on a shared file system).

How one run is executed (:func:`execute_run`, a Dask task)
----------------------------------------------------------
The task starts a child process ``python -m studies.dispatch SCENE OUT`` and waits for it:

- the child holds the output folder's lock (:mod:`compute.output_folder`, an exclusive
  ``fcntl.flock`` on ``OUT/.lock``) while it computes, so that two runs never write the same folder (e.g. an orphan of a killed study and its restart: the second
  waits for the first, then finds COMPLETE and skips);
- the child asks the kernel to kill it when its parent (the worker) dies (Linux
  ``PR_SET_PDEATHSIG``): killing the study kills its runs, they resume from their checkpoints;
- the child always runs with ``resume=True`` (compute.run: from ``OUT/checkpoint`` when there is
  one, else from the scene);
- the run starts with ``threads`` threads (``--threads``, default 1: the runs, not the threads,
  fill the cores: two runs of two threads each would oversubscribe two cores,
  benchmarks/results/threads.md); OpenMP and BLAS threads are capped to it, while numba's pool
  (NUMBA_NUM_THREADS) is sized for the cores of the machine so that the run can be given more
  (below);
- its stdout and stderr are appended to ``OUT/compute.log``;
- the folder holding this ``studies`` package goes first on the child's PYTHONPATH, so that the
  child imports the same code from any working folder, installed or not.

Freed cores go to the runs still going
--------------------------------------
When a study has more runs than workers, its last runs would go on with ``threads`` threads each
while the workers that finished sit idle. So once no run is left to start, the dispatcher gives
each host's cores (its workers' threads × ``threads``) to the runs going on it: a run's share is
:func:`core_shares` (cores // runs, the remainder to the runs started first, never below
``threads``), written atomically to ``OUT/threads`` (compute.files.write_text) whenever it
changes; the run reads that file after every step (one stat; :class:`compute.threads.ThreadsFile`)
and uses that many threads from its next step (capped to its numba pool). Its results do not
depend on it (the body-group kernels are per body, tests/compute/test_threads_file.py); a soft
group gains from 2 threads only from 400 bodies on (compute.threads.for_bodies). The
dispatcher writes ``OUT/threads`` = ``threads`` before starting a run (a file left by a killed
study does not carry over) and removes it when the run ends. The hosts are told apart by the
workers' addresses, and a run's host by the scheduler's ``processing`` (a round trip every
``POLL`` s once the queue is empty): a run is never handed another machine's cores.

Stopping a study
----------------
SIGINT (Ctrl-C) or SIGTERM to the dispatching process starts no further run and asks each
running run to stop after its step by a file ``OUT/STOP`` (compute.run: it checkpoints and dies
by SIGTERM, ``killed`` below, resumed by the next dispatch); the dispatcher records their
outcomes, then returns. A second signal ends the dispatcher at once: its runs then die with their
workers, losing the steps since their last checkpoint. Why a file: the runs are processes started
by the workers, possibly on other machines, which the dispatcher only sees through their folders.

Statuses (:class:`RunResult.status`): ``complete`` (the child wrote OUT/COMPLETE), ``incomplete``
(the child finished the loading program but wrote OUT/INCOMPLETE: some stage not equilibrated or
some contact solve above its tolerance, :mod:`compute.summary`), ``skipped`` (OUT/COMPLETE or
OUT/INCOMPLETE was already there: the run is finished), ``failed`` (OUT/FAILED holds the diagnosis: a numerical failure
or a file it could not write, written by compute, or a scene error / exception written here with the log's tail), ``killed``
(the child died by a signal: nothing is marked, the next dispatch resumes it), ``lost`` (the
Dask task itself failed, e.g. its worker died repeatedly), ``not started`` (the study was asked to
stop before its turn). A run that fails never stops the
others. Runs with OUT/FAILED are skipped by later dispatches unless ``retry_failed``.

Every outcome is appended, as one JSON object per line, to ``log_file`` when given (the study's
record of what ran when). While runs are going, the overall progress (ended runs plus the stage
fractions of the running ones) and each running run's stage, P and φ are shown, read from the
runs' OUT/progress.json (:mod:`compute.progress`).
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass
from pathlib import Path

from compute.progress import Display, read_progress
from compute.summary import run_status

__all__ = ["RunSpec", "RunResult", "child_environment", "core_shares", "dispatch", "execute_run", "local_cluster",
           "run_times"]

LOG = "compute.log"
POLL = 2.0  # seconds between two looks at the running runs' progress
CHILD_ALREADY_COMPLETE = 10  # child exit code: another process completed the run meanwhile
_CHILD_CODES = {0: "complete", CHILD_ALREADY_COMPLETE: "skipped", 2: "failed", 3: "failed", 4: "failed", 1: "failed"}
_THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")  # NUMBA_NUM_THREADS: the pool


def core_shares(cores: int, runs: int, least: int = 1) -> list[int]:
    """Threads of each of ``runs`` runs sharing ``cores``: cores // runs, the remainder to the
    first runs, and never fewer than ``least`` (a run keeps the threads it started with)."""
    if runs <= 0:
        return []
    base, extra = divmod(cores, runs)
    return [max(least, base + (k < extra)) for k in range(runs)]


def _pool_size(threads: int) -> int:
    """NUMBA_NUM_THREADS of a run process: the cores this process may use (at least ``threads``)."""
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        cores = os.cpu_count() or 1
    return max(int(threads), cores)


@dataclass(frozen=True)
class RunSpec:
    """One run: a ``name`` (unique in a dispatch), its scene folder and its output folder."""

    name: str
    scene: Path
    out: Path


@dataclass
class RunResult:
    """Outcome of one run (see the module docstring for ``status``); ``wall_time`` in seconds of
    this dispatch (0 when skipped); ``peak_mib`` the peak resident memory of its run process in MiB
    (0 when skipped; of this dispatch's process only, for a resumed run); ``resumed`` the child
    started from a checkpoint."""

    name: str
    status: str
    wall_time: float = 0.0
    peak_mib: float = 0.0
    resumed: bool = False
    message: str = ""


def _show_progress(display: Display, ended: int, running: list[RunSpec]) -> None:
    """Overall progress: ended runs plus the stage fractions of the running ones (their
    OUT/progress.json), and each running run's stage, P and φ."""
    done, parts = float(ended), []
    for spec in running:
        r = read_progress(spec.out)
        if r is None:
            parts.append(f"{spec.name} starting")
            continue
        done += min(r["stage"], r["stages"]) / max(r["stages"], 1)
        parts.append(f"{spec.name} stage {min(r['stage'] + 1, r['stages'])}/{r['stages']} P {r['pressure']:.3g} "
                     f"phi {r['phi']:.4f}")
    display.update(done, f"{ended}/{display.total} runs ended; " + "; ".join(parts))


def run_times(log_file: str | Path) -> dict[str, float]:
    """{run name: wall seconds of the dispatches that ran it, summed over resumptions} from a
    dispatch log (``log_file`` of :func:`dispatch`; {} when there is none)."""
    times: dict[str, float] = {}
    log = Path(log_file)
    if log.is_file():
        for line in log.read_text().splitlines():
            entry = json.loads(line)
            if entry["status"] in ("complete", "incomplete", "killed", "failed"):
                times[entry["name"]] = times.get(entry["name"], 0.0) + entry.get("wall_time", 0.0)
    return times


def _tail(path: Path, lines: int = 15) -> str:
    try:
        return "".join(path.read_text(errors="replace").splitlines(keepends=True)[-lines:])
    except OSError:
        return ""


def child_environment(threads: int) -> dict[str, str]:
    """The environment of a run's child process: this process's, with ``threads`` threads for
    OpenMP and BLAS, numba's pool sized for the freed cores (module docstring), this package
    importable, and without the malloc settings a Dask worker runs under.

    Why the last: Dask's nanny starts its workers with ``MALLOC_TRIM_THRESHOLD_`` = 65536 (to
    give a worker's freed memory back to the system), and a child inherits it. Setting it turns
    off glibc's dynamic mmap threshold, so that every array above 128 kB a run allocates is
    mapped and unmapped again, its pages faulted in anew each time: a 1500-disk run spent 30 %
    of its CPU time in the kernel (benchmarks/results/dispatch_malloc.md)."""
    env = dict(os.environ)
    env.pop("MALLOC_TRIM_THRESHOLD_", None)
    env.update({k: str(int(threads)) for k in _THREAD_VARIABLES})
    env["NUMBA_NUM_THREADS"] = str(_pool_size(threads))  # room for the freed cores (module docstring)
    env["SOFTRIGID_PARENT_PID"] = str(os.getpid())
    # the child imports this package whatever its working folder: the folder holding studies/ first
    env["PYTHONPATH"] = os.pathsep.join([str(Path(__file__).resolve().parents[1])] +
                                        [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p])
    return env


def execute_run(scene: str | Path, out: str | Path, threads: int = 1, retry_failed: bool = False,
                checkpoint_minutes: float | None = None) -> dict:
    """Run one scene in a child process (module docstring); never raises for a failed run.
    ``checkpoint_minutes``: also checkpoint after that much wall time (compute.run.Run).

    Returns the fields of :class:`RunResult` but ``name`` as a dict (plain data for Dask)."""
    scene, out = Path(scene).resolve(), Path(out).resolve()
    status = run_status(out)
    if status in ("complete", "incomplete"):
        return {"status": "skipped", "message": f"{status.upper()} exists"}
    if status == "failed" and not retry_failed:
        return {"status": "failed", "message": "not retried (FAILED exists): " + _tail(out / "FAILED", 3).strip()}
    out.mkdir(parents=True, exist_ok=True)
    resumed = status == "partial"
    env = child_environment(threads)
    cmd = [sys.executable, "-m", "studies.dispatch", str(scene), str(out), "--threads", str(int(threads))]
    if retry_failed:
        cmd.append("--retry-failed")
    if checkpoint_minutes is not None:
        cmd += ["--checkpoint-minutes", repr(float(checkpoint_minutes))]
    t0 = time.perf_counter()
    with (out / LOG).open("a") as log:
        log.write(f"=== {time.strftime('%Y-%m-%d %H:%M:%S')} pid {os.getpid()} on {os.uname().nodename}: "
                  f"{'resume' if resumed else 'start'} {scene} -> {out}\n")
        log.flush()
        child = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, env=env, stdin=subprocess.DEVNULL)
        _, wait_status, usage = os.wait4(child.pid, 0)
    code = os.waitstatus_to_exitcode(wait_status)
    wall, peak = time.perf_counter() - t0, round(usage.ru_maxrss / 1024.0, 1)  # ru_maxrss in KiB on Linux
    if code < 0:
        name = signal.Signals(-code).name if -code in signal.Signals._value2member_map_ else str(-code)
        return {"status": "killed", "wall_time": wall, "peak_mib": peak, "resumed": resumed,
                "message": f"run process killed by {name}; the next dispatch resumes it"}
    status = _CHILD_CODES.get(code, "failed")
    message = ""
    if status == "failed":
        if not (out / "FAILED").is_file():  # compute writes FAILED on numerical failures only
            (out / "FAILED").write_text(f"run process exited with code {code}; end of {LOG}:\n{_tail(out / LOG)}")
        message = _tail(out / "FAILED", 5).strip()
    elif status == "complete" and (out / "INCOMPLETE").is_file():
        status, message = "incomplete", _tail(out / "INCOMPLETE", 5).strip()
    elif status == "complete" and not (out / "COMPLETE").is_file():
        status, message = "failed", "run process exited normally without writing COMPLETE or INCOMPLETE"
        (out / "FAILED").write_text(message + "\n")
    return {"status": status, "wall_time": wall, "peak_mib": peak, "resumed": resumed, "message": message}


# Dask's own monitoring, slowed for the local cluster: its runs are long child processes that the
# workers only start and wait for, while by default every worker samples its threads for the
# profiler, checks its event loop, its memory and the system many times a second. On a machine
# with one core per run that monitoring is taken from the runs
# (benchmarks/results/dispatch_overhead.md).
QUIET = {"distributed.worker.profile.enabled": False, "distributed.worker.memory.monitor-interval": "1s",
         "distributed.admin.tick.interval": "1s", "distributed.admin.system-monitor.interval": "5s"}


def local_cluster(n_workers: int = 2, threads_per_worker: int = 1):
    """The default cluster: worker processes with one thread each, no dashboard, Dask's monitoring
    slowed (:data:`QUIET`).

    (The scheduler's small HTTP server still binds a port: 8787, or any free one when 8787 is taken
    by another cluster, which distributed warns about; that warning is silenced here.)"""
    import warnings

    import dask
    from dask.distributed import LocalCluster

    with warnings.catch_warnings(), dask.config.set(QUIET):
        warnings.filterwarnings("ignore", message="Port .* is already in use")
        return LocalCluster(n_workers=n_workers, threads_per_worker=threads_per_worker, processes=True,
                            dashboard_address=None)


def dispatch(runs: Iterable[RunSpec], scheduler: str | None = None, n_workers: int = 2, threads: int = 1,
             retry_failed: bool = False, log: Callable[[str], None] | None = print,
             log_file: str | Path | None = None, progress: bool | Display = True,
             checkpoint_minutes: float | None = None) -> list[RunResult]:
    """Run every run of ``runs`` not yet complete, at most one per worker thread at a time,
    started in the order of ``runs`` (put the longest first).

    scheduler: a Dask scheduler address (``tcp://host:8786``); None starts
    :func:`local_cluster` (``n_workers`` workers, one thread each) for the duration of the call.
    threads: threads per run at first (more once no run is left to start: module docstring). checkpoint_minutes: each run also checkpoints after that
    much wall time (compute.run.Run). Returns one :class:`RunResult` per run, in the order
    of ``runs``; also appended to ``log_file`` (JSON lines) when given. ``progress``: show the
    overall progress and each running run's stage (:mod:`compute.progress`: a bar on a terminal,
    a plain line every 30 s otherwise; or the Display given), read from the runs' OUT/progress.json
    every ``POLL`` s.
    """
    runs = list(runs)
    names = [r.name for r in runs]
    if len(set(names)) != len(names):
        raise ValueError(f"runs: names must be unique, got {names}")
    say = log or (lambda msg: None)
    results: dict[str, RunResult] = {}

    def record(result: RunResult) -> None:
        results[result.name] = result
        extra = f" ({result.wall_time:.1f} s{', resumed' if result.resumed else ''})" if result.wall_time else ""
        say(f"[{result.status}] {result.name}{extra}" + (f": {result.message}" if result.message and
                                                          result.status != "skipped" else ""))
        if log_file is not None:
            with Path(log_file).open("a") as stream:
                stream.write(json.dumps({"time": time.strftime("%Y-%m-%dT%H:%M:%S"), **asdict(result)}) + "\n")

    todo = []
    for r in runs:
        status = run_status(r.out)
        if status in ("complete", "incomplete"):
            record(RunResult(r.name, "skipped", message=f"{status.upper()} exists"))
        elif status == "failed" and not retry_failed:
            record(RunResult(r.name, "failed", message="not retried (FAILED exists; use retry_failed)"))
        else:
            todo.append(r)
    if todo:
        from dask.distributed import Client, wait

        cluster = None if scheduler else local_cluster(n_workers)
        try:
            with Client(scheduler or cluster) as client:
                say(f"dispatching {len(todo)} run(s) to {scheduler or 'a local cluster'} "
                    f"({len(client.scheduler_info().get('workers', {}))} workers)")
                # the client hands out one run per worker thread and the next one when a run ends:
                # runs start in the order given, and none waits behind a long run on a busy worker
                # while another worker is idle (Dask may otherwise place tasks that way)
                queue, running = list(todo), {}
                shown = progress if isinstance(progress, Display) else Display(len(todo), "study") if progress else None

                shares: dict[RunSpec, int] = {}  # threads last written to each running run's OUT/threads

                from compute.run import STOP_FILE
                from compute.threads import THREADS_FILE

                def fill() -> None:
                    slots = max(1, sum(client.nthreads().values()))
                    while queue and len(running) < slots:
                        spec = queue.pop(0)
                        _write_threads(spec.out, threads)  # not a share left by a killed study
                        _remove(spec.out, STOP_FILE)  # nor a stop asked of it then
                        shares[spec] = threads
                        future = client.submit(execute_run, str(spec.scene), str(spec.out), threads, retry_failed,
                                               checkpoint_minutes, key=f"run-{spec.name}-{time.time_ns()}", pure=False)
                        running[future] = spec

                fill()
                stopping = False
                with _StopRequest() as stop:
                    while running:
                        if stop.asked and not stopping:  # no new run; the running ones asked to stop
                            stopping = True
                            say(f"stopping: {len(queue)} run(s) not started; asking "
                                + ", ".join(spec.name for spec in running.values()) + " to stop after their step")
                            for spec in queue:
                                record(RunResult(spec.name, "not started", message="the study was asked to stop"))
                            queue.clear()
                            for spec in running.values():
                                _ask_stop(spec.out)
                        try:
                            wait(list(running), timeout=POLL, return_when="FIRST_COMPLETED")
                        except TimeoutError:
                            pass
                        for future in [f for f in running if f.done()]:
                            spec = running.pop(future)
                            shares.pop(spec, None)
                            _remove(spec.out, THREADS_FILE)
                            try:
                                record(RunResult(spec.name, **future.result()))
                            except Exception as exc:  # the task itself died (worker lost, ...)
                                record(RunResult(spec.name, "lost", message=f"{type(exc).__name__}: {exc}"))
                        fill()
                        if not queue and running:
                            try:
                                _hand_out_cores(client, running, threads, shares, say)
                            except Exception as exc:  # a core not handed out costs time, never the study
                                say(f"warning: freed cores not handed out: {type(exc).__name__}: {exc}")
                        if shown is not None:
                            _show_progress(shown, len(todo) - len(queue) - len(running), list(running.values()))
                if shown is not None:
                    shown.mark(f"{len(todo)}/{len(todo)} runs ended")
                    shown.close()
        finally:
            if cluster is not None:
                cluster.close()
    return [results[n] for n in names]


def _write_threads(out: Path, n: int) -> None:
    from compute import files
    from compute.threads import THREADS_FILE

    Path(out).mkdir(parents=True, exist_ok=True)
    files.write_text(Path(out) / THREADS_FILE, f"{int(n)}\n")


class _StopRequest:
    """While in the block, a SIGINT or SIGTERM sets ``asked`` instead of stopping the process, and
    gives both signals back their default handlers, so that a second one stops it at once (module
    docstring, "Stopping a study"). Off the main thread (where signal handlers cannot be set) it
    does nothing."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self):
        self.asked, self._previous = False, {}

    def __enter__(self):
        import threading

        if threading.current_thread() is threading.main_thread():
            self._previous = {sig: signal.signal(sig, self._ask) for sig in self.SIGNALS}
        return self

    def _ask(self, signum, frame) -> None:
        self.asked = True
        for sig in self.SIGNALS:
            signal.signal(sig, signal.SIG_DFL if sig == signal.SIGTERM else signal.default_int_handler)

    def __exit__(self, *exc) -> None:
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)


def _ask_stop(out: Path) -> None:
    """Ask the run writing ``out`` to stop after its step (compute.run.STOP_FILE)."""
    from compute import files
    from compute.run import STOP_FILE

    try:
        files.write_text(Path(out) / STOP_FILE, "asked by the study's dispatcher\n")
    except Exception:  # a run that cannot be asked goes on; a second signal still stops the study
        pass


def _remove(out: Path, name: str) -> None:
    """Remove the file ``name`` of a run's folder if it is there (best effort)."""
    try:
        (Path(out) / name).unlink(missing_ok=True)
    except OSError:
        pass


def _hand_out_cores(client, running: dict, threads: int, shares: dict, say: Callable[[str], None]) -> None:
    """Give each host's cores to the runs going on it (module docstring): OUT/threads of each run
    whose share changed. Nothing is written while some run is not yet placed on a worker."""
    from distributed.comm import get_address_host

    nthreads = client.nthreads()
    where = {key: worker for worker, keys in client.processing().items() for key in keys}
    by_host: dict[str, list] = {}
    for future, spec in running.items():  # in the order the runs started
        worker = where.get(future.key)
        if worker is None:
            return  # not placed yet: next time
        by_host.setdefault(get_address_host(worker), []).append(spec)
    for host, specs in by_host.items():
        cores = threads * sum(n for w, n in nthreads.items() if get_address_host(w) == host)
        for spec, n in zip(specs, core_shares(cores, len(specs), threads)):
            if shares.get(spec) != n:
                try:
                    _write_threads(spec.out, n)
                except Exception as exc:  # a share not given costs time, not results
                    say(f"warning: could not give {spec.name} {n} threads: {exc}")
                    continue
                say(f"{spec.name}: {n} threads (cores freed on {host})")
                shares[spec] = n


# --------------------------------------------------------------------------- the child process


def _die_with_parent() -> None:
    """Linux: SIGKILL this process when its parent dies; exit now if it is already gone."""
    parent = int(os.environ.get("SOFTRIGID_PARENT_PID", "0"))
    if sys.platform.startswith("linux"):
        import ctypes

        try:
            ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
        except OSError:
            pass
    if parent and os.getppid() != parent:
        sys.exit(f"parent {parent} is gone: not starting")


def _numba_pool() -> int:
    import numba

    return numba.config.NUMBA_NUM_THREADS


def _child(argv: list[str] | None = None) -> int:
    """``python -m studies.dispatch SCENE OUT [--retry-failed] [--checkpoint-minutes M] [--threads N]``: one run,
    under OUT's lock."""
    import argparse
    import traceback

    from compute import output_folder
    from compute.errors import InputError

    p = argparse.ArgumentParser(prog="python -m studies.dispatch",
                                description="Run one scene under its output folder's lock (used by dispatch).")
    p.add_argument("scene")
    p.add_argument("out")
    p.add_argument("--retry-failed", action="store_true")
    p.add_argument("--checkpoint-minutes", type=float, default=None)
    p.add_argument("--threads", type=int, default=None, help="threads at first (default: NUMBA_NUM_THREADS)")
    a = p.parse_args(argv)
    _die_with_parent()
    out = Path(a.out)
    try:
        try:
            key = output_folder.acquire(out)
        except InputError:
            print(f"{out} is locked by another process: waiting for it", flush=True)
            key = output_folder.acquire(out, wait=True)
    except InputError as exc:
        print(f"error: {exc}", flush=True)
        return 2
    try:
        status = run_status(out)
        if status in ("complete", "incomplete"):
            print(f"{status.upper()} exists: nothing to do", flush=True)
            return CHILD_ALREADY_COMPLETE
        if status == "failed":
            if not a.retry_failed:
                print("FAILED exists: not retried", flush=True)
                return 3
            (out / "FAILED").unlink()
        from compute.errors import OutputWriteError, SimulationError
        from compute.run import run
        from compute.threads import configure

        # --threads at first, up to NUMBA_NUM_THREADS later (OUT/threads), passive when idle
        configure(None if a.threads is None else min(a.threads, _numba_pool()))

        try:
            run(a.scene, out, resume=True, log=lambda msg: print(msg, flush=True), checkpoint_minutes=a.checkpoint_minutes)
        except InputError as exc:
            (out / "FAILED").write_text(f"input error: {exc}\n")
            print(f"error: {exc}", flush=True)
            return 2
        except SimulationError as exc:  # compute.run wrote FAILED
            print(f"simulation failed: {exc}", flush=True)
            return 3
        except OutputWriteError as exc:  # compute.run wrote FAILED if it could
            print(f"write failed: {exc}", flush=True)
            return 4
        except Exception:
            (out / "FAILED").write_text("exception in the run:\n" + traceback.format_exc())
            traceback.print_exc()
            return 1
    finally:
        output_folder.release(key)
    return 0


if __name__ == "__main__":
    sys.exit(_child())
