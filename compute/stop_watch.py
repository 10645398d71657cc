"""A second SIGTERM that stops a run at once, even while it is inside a compiled kernel.

Python runs a signal handler only between bytecodes of the main thread, so a run inside a numba
kernel (one contact solve of a large soft packing can take minutes) acts on neither the first
SIGTERM (stop after the step, :mod:`compute.run`) nor the second (stop now) until the kernel
returns. CPython's C-level handler still notes each signal when it arrives and, when a wakeup
file descriptor is set (:func:`signal.set_wakeup_fd`), writes the signal's number to it. A small
watcher process reads that pipe and, at the second SIGTERM, kills the run with SIGKILL: a killed
run, resumed from its last checkpoint by ``--resume`` or the study's next dispatch, having lost
the steps since. A first SIGTERM handled between steps resets the handler to the default, and
a second one then kills the run by itself: the watcher only acts when Python could not.

The watcher ends when the run closes the pipe (the block's end, or the run's death).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
from contextlib import contextmanager

# The watcher: counts the SIGTERMs in the bytes the run's C handler writes (one byte, the signal's
# number, per signal), SIGKILLs its parent at the second, ends at the end of the pipe.
WATCHER = """
import os, signal
parent, seen = os.getppid(), 0
while data := os.read(0, 256):
    seen += data.count(signal.SIGTERM)
    if seen >= 2:
        os.kill(parent, signal.SIGKILL)
        break
"""


@contextmanager
def second_sigterm_kills():
    """Within the block, a second SIGTERM kills this process at once (module docstring). Off the
    main thread (no wakeup descriptor can be set there) it does nothing; the caller installs its
    own SIGTERM handler (a wakeup descriptor only sees signals Python handles)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    read, write = os.pipe()
    os.set_blocking(write, False)  # the C handler must never block on a full pipe
    try:
        watcher = subprocess.Popen([sys.executable, "-I", "-S", "-c", WATCHER], stdin=read)
    finally:
        os.close(read)
    previous = None
    try:
        previous = signal.set_wakeup_fd(write, warn_on_full_buffer=False)
        yield
    finally:  # the pipe closed in any case: the watcher reads its end and exits
        if previous is not None:
            signal.set_wakeup_fd(previous)
        os.close(write)
        watcher.wait()
