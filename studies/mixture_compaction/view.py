"""A study made of runs of other study folders, for post.py to analyse together: writes
DIR/study.json listing the runs FOLDER/NAME given (their scenes and outputs stay where they are,
referred to by relative paths) and DIR/dispatch.jsonl with their lines of each folder's dispatch
log (run times). Then ``post.py --workdir DIR`` writes DIR/post as for any study.

    python -m studies.mixture_compaction.view --workdir DIR --runs FOLDER/NAME [FOLDER/NAME ...]

Why: a large study grows over sessions in several folders (e.g. one per contact formulation),
and the paper fits its law over all its runs at once. The folders must share the study settings
that the analysis reads (N, elements, pressures, material); a run's own scene options
(pre.py --set) may differ and are listed in each run's entry as ``overrides``. Two runs of one
name are refused (the analysis keys runs by name).
"""

if not __package__:  # run as a file (python studies/X/stage.py): studies/entry.py
    import pathlib, sys; sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2]))
    from studies.entry import run_as_file; run_as_file(__file__)

import argparse
import json
import os
import sys
from pathlib import Path

SHARED = ("study", "n", "element", "elements", "volumetric", "pressures_over_E", "young", "poisson")


def view(workdir: Path, runs: list[str]) -> dict:
    """The study of ``runs`` (FOLDER/NAME each) written to ``workdir``; returns it. Raises
    ValueError naming the file and field on a missing run, a duplicate name or a setting that
    differs between folders."""
    workdir.mkdir(parents=True, exist_ok=True)
    studies, entries, log = {}, [], []
    settings = None
    for item in runs:
        folder, _, name = item.rstrip("/").rpartition("/")
        path = Path(folder) / "study.json"
        if folder not in studies:
            if not path.is_file():
                raise ValueError(f"{path}: not found (--runs {item}: expected FOLDER/NAME of a study folder)")
            studies[folder] = json.loads(path.read_text())
        study = studies[folder]
        if settings is None:
            settings, first = {k: study.get(k) for k in SHARED}, path
        for key in SHARED:
            if study.get(key) != settings[key]:
                raise ValueError(f"{path}: field '{key}' is {study.get(key)!r}, expected {settings[key]!r} as in "
                                 f"{first} (runs analysed together share their study settings)")
        run = next((r for r in study["runs"] if r["name"] == name), None)
        if run is None:
            raise ValueError(f"{path}: field 'runs' has no run named {name!r} (--runs {item})")
        if any(e["name"] == name for e in entries):
            raise ValueError(f"--runs {item}: a run named {name!r} is already in the view (names must be unique)")
        here = Path(os.path.relpath(folder, workdir))
        entries.append({**run, "scene": str(here / run["scene"]), "out": str(here / run["out"]),
                        "overrides": study.get("overrides", {}), "from": str(here)})
        dispatch = Path(folder) / "dispatch.jsonl"
        if dispatch.is_file():
            log += [line for line in dispatch.read_text().splitlines() if json.loads(line)["name"] == name]
    out = {**settings, "overrides": {}, "jamming": [], "runs": entries,
           "pre_seconds": sum(s.get("pre_seconds", 0.0) for s in studies.values())}
    (workdir / "study.json").write_text(json.dumps(out, indent=1) + "\n")
    (workdir / "dispatch.jsonl").write_text("".join(line + "\n" for line in log))
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--workdir", required=True, help="the view's folder (DIR): study.json, dispatch.jsonl, later post/")
    p.add_argument("--runs", nargs="+", required=True, metavar="FOLDER/NAME", help="runs of study folders")
    a = p.parse_args(argv)
    try:
        study = view(Path(a.workdir), a.runs)
    except ValueError as exc:
        p.error(str(exc))
    print(f"{Path(a.workdir) / 'study.json'}: {len(study['runs'])} runs from "
          f"{len({r['from'] for r in study['runs']})} study folders")
    return 0


if __name__ == "__main__":
    sys.exit(main())
