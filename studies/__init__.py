"""The paper's studies, each three stages: ``pre``, ``compute``, ``post``.

Run a stage any of three ways, e.g.::

    python -m studies.mixture_compaction.pre --workdir runs/mixture   # from the repository root
    python studies/mixture_compaction/pre.py --workdir runs/mixture   # from any folder
    mixture-compaction-pre --workdir runs/mixture                     # once installed (pyproject.toml)

(a script run as a file first puts the repository on ``sys.path`` in place of its own folder,
whose pre.py, compute.py, post.py would shadow the toolkit's packages: :mod:`studies.entry`). The
scripts hold argument parsing, the paper's constants and calls into the library (pre, compute,
post); :mod:`studies.dispatch` runs a study's many scenes on a Dask cluster.
"""
