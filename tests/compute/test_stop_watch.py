"""A second SIGTERM kills a run stuck inside a compiled kernel (compute.stop_watch)."""

from __future__ import annotations

import signal
import subprocess
import sys
import time

# A process as a run is: a Python SIGTERM handler (which would write a file), the watcher's block,
# then a numba kernel that runs for minutes without returning to Python.
STUCK = """
import signal, sys, time
import numba
from pathlib import Path
from compute.stop_watch import second_sigterm_kills

handled = Path(sys.argv[1])
signal.signal(signal.SIGTERM, lambda *a: handled.write_text("handled"))

@numba.njit(cache=False)
def spin(seconds):
    x, n = 0.0, int(seconds * 2e8)
    for i in range(n):
        x += (i % 7) * 1e-9
    return x

spin(1e-6)  # compiled before the signals come
with second_sigterm_kills():
    print("in kernel", flush=True)
    spin(300.0)
"""


def _start(tmp_path):
    proc = subprocess.Popen([sys.executable, "-c", STUCK, str(tmp_path / "handled")], stdout=subprocess.PIPE,
                            text=True)
    assert proc.stdout.readline().strip() == "in kernel"
    time.sleep(0.2)
    return proc


def test_second_sigterm_kills_a_process_inside_a_kernel(tmp_path):
    proc = _start(tmp_path)
    proc.send_signal(signal.SIGTERM)
    time.sleep(0.5)
    assert proc.poll() is None, "one SIGTERM is a request to stop after the step, not a kill"
    proc.send_signal(signal.SIGTERM)
    try:
        code = proc.wait(timeout=20)
    finally:
        proc.kill()
    assert code == -signal.SIGKILL
    assert not (tmp_path / "handled").exists(), "the kernel never returned: Python's handler cannot have run"


def test_the_watcher_ends_with_the_process(tmp_path):
    """Killed otherwise, the process leaves no watcher behind: it reads the end of the pipe."""
    proc = _start(tmp_path)
    children = subprocess.run(["pgrep", "-P", str(proc.pid)], capture_output=True, text=True).stdout.split()
    assert len(children) == 1
    proc.kill()
    proc.wait()
    deadline = time.time() + 10
    while time.time() < deadline and subprocess.run(["kill", "-0", children[0]], capture_output=True).returncode == 0:
        time.sleep(0.05)
    assert subprocess.run(["kill", "-0", children[0]], capture_output=True).returncode != 0
