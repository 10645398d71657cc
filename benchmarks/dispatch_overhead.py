"""What Dask's local cluster costs while it waits for the runs it started.

A study's runs are child processes that the cluster's workers start and wait for
(studies.dispatch). The CPU time the cluster's own processes take meanwhile (the parent with the
scheduler and the client, the workers and their nannies) is taken from the runs on a machine with
one core per run. This starts ``studies.dispatch.local_cluster`` as the studies do, once with
Dask's default configuration and once with ``studies.dispatch.QUIET``, gives each worker a task
that sleeps ``--seconds``, and prints the CPU used by every process of the cluster meanwhile, in
per cent of one core.

    python benchmarks/dispatch_overhead.py --seconds 30
"""

from __future__ import annotations

import argparse
import time


def nap(seconds: float) -> float:
    time.sleep(seconds)
    return seconds


def measure(quiet: bool, seconds: float, workers: int) -> dict:
    """{process: % of one core} of the cluster's processes while its workers sleep ``seconds``."""
    from unittest import mock

    import psutil
    from dask.distributed import Client

    from studies import dispatch

    with mock.patch.dict(dispatch.QUIET, clear=not quiet):  # empty: Dask's defaults
        cluster = dispatch.local_cluster(workers)
    with cluster, Client(cluster) as client:
        client.wait_for_workers(workers)
        time.sleep(2.0)  # start-up over
        procs = [psutil.Process()] + psutil.Process().children(recursive=True)
        before = {p.pid: sum(p.cpu_times()[:2]) for p in procs}
        client.gather([client.submit(nap, seconds, pure=False) for _ in range(workers)])
        names = {p.pid: ("parent (scheduler, client)" if p.pid == procs[0].pid else
                         "worker" if "spawn_main" in " ".join(p.cmdline()) else p.name()) for p in procs}
        used = {p.pid: sum(p.cpu_times()[:2]) - before[p.pid] for p in procs if p.is_running()}
    return {f"{names[pid]} {pid}": round(100.0 * t / seconds, 1) for pid, t in used.items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=30.0)
    ap.add_argument("--workers", type=int, default=2)
    a = ap.parse_args()
    for quiet in (False, True):
        shares = measure(quiet, a.seconds, a.workers)
        print(f"{'QUIET' if quiet else 'default'}: {sum(shares.values()):.1f} % of one core in all; {shares}")


if __name__ == "__main__":
    main()
