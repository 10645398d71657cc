"""MPRGP gives the same impulses to the last bit whatever BLAS kernel the processor selects.

OpenBLAS picks its kernels for the processor at run time (OPENBLAS_CORETYPE forces one); they
sum a dot product in different orders. A solver that calls the BLAS inside its iteration then
rounds differently on another machine, and a frictionless jamming, whose path amplifies the
last bits, ends on another packing. The problem is built once here (its construction calls the
BLAS too) and solved in child processes, each forced onto another kernel."""

from __future__ import annotations

import pickle
import subprocess
import sys

import numpy as np

from tests.blas_kernels import kernel_environment, needs_openblas_kernels

from .problems import random_problem

CHILD = """
import hashlib, pickle, sys
import threadpoolctl
from compute.solvers.mprgp import MPRGP
problem = pickle.load(open(sys.argv[1], "rb"))
report = MPRGP(1e-12, 5000).solve(problem)
kernels = {i["architecture"] for i in threadpoolctl.threadpool_info() if i["internal_api"] == "openblas"}
print(",".join(sorted(kernels)), report.iterations, hashlib.sha256(problem.impulse.tobytes()).hexdigest())
"""


@needs_openblas_kernels
def test_mprgp_rounds_alike_on_every_blas_kernel(tmp_path):
    """A frictionless problem of 400 contacts (rigid and soft dofs) solved to 1e-12 under
    OpenBLAS's Prescott (SSE3) and Haswell (AVX2) kernels and the processor's own: the same
    iterations and impulses, byte for byte; each child reports the kernel it ran."""
    problem = random_problem(np.random.default_rng(11), "mixed", 400)
    problem.mu[:] = 0.0
    path = tmp_path / "problem.pkl"
    path.write_bytes(pickle.dumps(problem))
    answers = {}
    for kernel in ("Prescott", "Haswell", None):
        r = subprocess.run([sys.executable, "-c", CHILD, str(path)], env=kernel_environment(kernel),
                           capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, r.stderr
        ran, iterations, digest = r.stdout.split()
        answers[kernel] = (ran, int(iterations), digest)
    assert answers["Prescott"][0] != answers["Haswell"][0], answers  # two kernels did run: two orders of summing
    assert min(i for _, i, _ in answers.values()) > 10, answers  # a real solve, not the warm start
    assert len({(i, d) for _, i, d in answers.values()}) == 1, answers
