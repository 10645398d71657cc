"""Saying that numba is compiling, so that a first run's slow start is not read as its speed.

The toolkit's kernels are numba functions cached on disk (``cache=True``: in ``__pycache__``
beside the sources, or under NUMBA_CACHE_DIR). The first run after an installation, or after an
edit of a kernel's source, compiles each as it first calls it, from its first step on; later runs
load them from the cache (the cold and warm times of a small run: benchmarks/results/first_run.md). :class:`CompileNotice` listens to numba's ``numba:compile``
event, which numba fires only when it compiles a function, not when it loads one from the cache,
and says :data:`MESSAGE` once, at the first compilation; on a warm cache it says nothing.
"""

from __future__ import annotations

from collections.abc import Callable

from numba.core import event

MESSAGE = "compiling numba kernels (once per install; cached afterwards) …"
KIND = "numba:compile"


class CompileNotice(event.Listener):
    """Calls ``say(MESSAGE)`` at the first numba compilation between :meth:`start` and
    :meth:`stop` (also a context manager); ``said``: whether it did."""

    def __init__(self, say: Callable[[str], None]):
        self._say = say
        self.said = False
        self._listening = False

    def on_start(self, ev) -> None:
        if not self.said:
            self.said = True
            self._say(MESSAGE)

    def on_end(self, ev) -> None:
        pass

    def start(self) -> CompileNotice:
        if not self._listening:
            event.register(KIND, self)
            self._listening = True
        return self

    def stop(self) -> None:
        if self._listening:
            event.unregister(KIND, self)
            self._listening = False

    def __enter__(self) -> CompileNotice:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()
