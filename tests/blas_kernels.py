"""Children forced onto an OpenBLAS kernel (OPENBLAS_CORETYPE), for the tests that a run rounds
alike on every processor (compute.fixed_order): the skip mark and a child's environment."""

from __future__ import annotations

import os
import platform

import pytest


def _openblas() -> bool:
    """numpy's BLAS is OpenBLAS (numpy imported first: threadpoolctl sees only loaded libraries,
    and this runs when a test module is imported)."""
    import numpy  # noqa: F401
    import threadpoolctl

    return any(i["internal_api"] == "openblas" for i in threadpoolctl.threadpool_info())


needs_openblas_kernels = pytest.mark.skipif(
    platform.machine() != "x86_64" or not _openblas(),
    reason="needs numpy's BLAS to be OpenBLAS on x86-64 (whose core types OPENBLAS_CORETYPE names)")


def kernel_environment(kernel: str | None) -> dict[str, str]:
    """This process's environment with OpenBLAS forced onto ``kernel`` (None: the processor's own)
    and one BLAS thread."""
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1")
    env.pop("OPENBLAS_CORETYPE", None)
    if kernel:
        env["OPENBLAS_CORETYPE"] = kernel
    return env
