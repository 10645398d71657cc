"""The paper's studies, each three stages: ``pre``, ``compute``, ``post``.

Run a stage as a module from the repository root, e.g.::

    python -m studies.mixture_compaction.pre --workdir runs/mixture

(never as ``python studies/.../pre.py``: a script's own folder goes first on ``sys.path``, and
its name would then shadow the toolkit's package of the same name). The scripts hold argument
parsing, the paper's constants and calls into the library (pre, compute, post).
"""
