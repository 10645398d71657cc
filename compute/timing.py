"""Wall-clock time per phase of the computation (what benchmarks/soft_step_cost.py reports)."""

from __future__ import annotations

import time
from collections import defaultdict
from contextlib import contextmanager


class PhaseTimes:
    """Seconds and calls per phase name, accumulated over a run: ``with times("assembly"): ...``."""

    def __init__(self):
        self.seconds: dict[str, float] = defaultdict(float)
        self.calls: dict[str, int] = defaultdict(int)

    @contextmanager
    def __call__(self, phase: str):
        t0 = time.perf_counter()
        try:
            yield
        finally:
            self.seconds[phase] += time.perf_counter() - t0
            self.calls[phase] += 1


TIMES = PhaseTimes()  # the process's phase times (one run per process)
