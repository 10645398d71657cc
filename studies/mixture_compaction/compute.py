"""Stage 2 of the mixture compaction study: runs every scene DIR/runs/<name>/scene into
DIR/runs/<name>/out, dispatched with Dask distributed (studies.dispatch): a local cluster of
--workers processes with one thread each by default, or the scheduler at --scheduler ADDRESS.

Runs whose OUT/COMPLETE exists are skipped; runs killed midway resume from their checkpoint; a run
that fails (OUT/FAILED) does not stop the others and is not retried unless --retry-failed. Ctrl-C
or SIGTERM stops the study without losing a step: no further run starts, the running ones stop
after their step with a checkpoint (a second signal stops at once). Every
outcome is appended to DIR/dispatch.jsonl (one JSON object per line: time, name, status,
wall_time, resumed, message). Exit status 0 when every run is complete, 1 otherwise.
"""

if not __package__:  # run as a file (python studies/X/stage.py): studies/entry.py
    import pathlib, sys; sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2]))
    from studies.entry import run_as_file; run_as_file(__file__)

import argparse
import json
import sys
import time
from pathlib import Path


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--workdir", required=True, help="study folder written by pre.py (DIR/study.json, DIR/runs)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="Dask scheduler address (e.g. tcp://host:8786); default: a local cluster")
    p.add_argument("--workers", type=int, default=2, help="local cluster: worker processes (default 2)")
    p.add_argument("--threads", type=int, default=1, help="numba/BLAS threads per run (default 1)")
    p.add_argument("--retry-failed", action="store_true", help="run again the runs that have OUT/FAILED")
    p.add_argument("--checkpoint-minutes", type=float, default=None, metavar="M",
                   help="each run also checkpoints after M minutes of wall time (long runs resumed in "
                        "another session lose at most M minutes; default: the scenes' step-counted checkpoints)")
    p.add_argument("--runs", nargs="+", metavar="NAME",
                   help="only these runs of the study (e.g. k0.5_mu0.2_s1; default: all)")
    a = p.parse_args(argv)
    if a.checkpoint_minutes is not None and not a.checkpoint_minutes > 0.0:
        p.error(f"--checkpoint-minutes: expected a positive number of minutes, got {a.checkpoint_minutes}")

    from studies.dispatch import RunSpec, dispatch

    w = Path(a.workdir)
    study_file = w / "study.json"
    if not study_file.is_file():
        p.error(f"{study_file}: not found (run pre.py --workdir {w} first)")
    study = json.loads(study_file.read_text())
    # heaviest first (more deformable bodies), so that the last runs to start are the short ones
    runs = sorted(study["runs"], key=lambda r: (-r["kappa"], r["mu"], r["seed"]))
    if a.runs:
        unknown = sorted(set(a.runs) - {r["name"] for r in runs})
        if unknown:
            p.error(f"--runs: {', '.join(unknown)} not in {study_file} (its runs: "
                    f"{', '.join(r['name'] for r in runs)})")
        runs = [r for r in runs if r["name"] in a.runs]
    specs = [RunSpec(r["name"], w / r["scene"], w / r["out"]) for r in runs]
    t0 = time.perf_counter()
    results = dispatch(specs, scheduler=a.scheduler, n_workers=a.workers, threads=a.threads,
                       retry_failed=a.retry_failed, log_file=w / "dispatch.jsonl",
                       checkpoint_minutes=a.checkpoint_minutes)
    counts = {}
    for r in results:
        counts[r.status] = counts.get(r.status, 0) + 1
    print(f"{len(results)} runs in {time.perf_counter() - t0:.1f} s: "
          + ", ".join(f"{n} {s}" for s, n in sorted(counts.items())))
    return 0 if all(r.status in ("complete", "skipped") for r in results) else 1


if __name__ == "__main__":
    sys.exit(main())
