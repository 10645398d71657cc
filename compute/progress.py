"""Live progress of long runs: in place on a terminal (a rich progress bar), as plain lines in a log.

:class:`Display` is the one way progress is shown: on a terminal (``interactive``), a bar over a
total with a status text updated in place; otherwise one plain line every ``interval`` seconds
and at every :meth:`Display.mark` (e.g. a run's end), so that a log file holds a
readable record instead of carriage returns.

:class:`RunProgress` is a run's progress: stage i/n, P/E, φ, steps, seconds per step and an ETA
(mean time of the finished stages times the stages left; P is the applied pressure, P/E in the
studies' reduced units), shown with a Display and written to
``OUT/progress.json`` (atomically, at most every ``interval`` seconds and at every stage end)
for whoever watches the run from outside, e.g. a study dispatching many runs
(:func:`studies.dispatch.dispatch`). From its start to its end, a RunProgress also shows once
that numba is compiling, when it first does (:mod:`compute.compiling`), so that a first run's
slow first steps are not read as the toolkit's speed.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

from compute import files

PROGRESS = "progress.json"
INTERVAL = 30.0  # seconds between two plain lines / two progress.json writes


def _duration(seconds: float | None) -> str:
    if seconds is None:
        return "?"
    seconds = int(round(seconds))
    h, rest = divmod(seconds, 3600)
    m, s = divmod(rest, 60)
    return f"{h}:{m:02d}:{s:02d}" if h else f"{m}:{s:02d}"


class Display:
    """Progress over ``total`` units: ``update(done, text)`` shows it (``done`` may be fractional).

    interactive: a rich bar in place (default: when ``stream`` is a terminal); else plain lines,
    at most one per ``interval`` seconds plus one per :meth:`mark`."""

    def __init__(self, total: float, description: str = "", stream=None, interactive: bool | None = None,
                 interval: float = INTERVAL):
        self.stream = stream if stream is not None else sys.stderr
        self.interactive = self.stream.isatty() if interactive is None else interactive
        self.total, self.description, self.interval = total, description, interval
        self._last_line = -float("inf")
        self._text = ""
        self._bar = None
        if self.interactive:
            from rich.console import Console
            from rich.progress import BarColumn, Progress, TaskProgressColumn, TextColumn

            self._bar = Progress(TextColumn("{task.description}"), BarColumn(), TaskProgressColumn(),
                                 TextColumn("{task.fields[status]}"), console=Console(file=self.stream),
                                 auto_refresh=False, transient=False)
            self._task = self._bar.add_task(description, total=total, status="")
            self._bar.start()

    def update(self, done: float, text: str) -> None:
        self._text = text
        if self._bar is not None:
            self._bar.update(self._task, completed=min(done, self.total), status=text)
            if time.monotonic() - self._last_line >= 0.1:  # at most 10 redraws a second
                self._last_line = time.monotonic()
                self._bar.refresh()
        elif time.monotonic() - self._last_line >= self.interval:
            self._line()

    def mark(self, text: str | None = None) -> None:
        """A milestone: always shown (a plain line, or the bar refreshed)."""
        if text is not None:
            self._text = text
        if self._bar is not None:
            self._bar.update(self._task, status=self._text)
            self._bar.refresh()
        else:
            self._line()

    def close(self) -> None:
        if self._bar is not None:
            self._bar.stop()

    def _line(self) -> None:
        self._last_line = time.monotonic()
        prefix = f"{self.description}: " if self.description else ""
        print(f"{prefix}{self._text}", file=self.stream, flush=True)


class RunProgress:
    """The progress of a run into ``out`` through ``n_stages`` stages (module docstring)."""

    def __init__(self, out: Path, n_stages: int, display: Display | None = None, interval: float = INTERVAL):
        self.out, self.n_stages, self.interval = Path(out), n_stages, interval
        self.display = display if display is not None else Display(n_stages, "compute", interval=interval)
        self._t0 = time.monotonic()
        self._steps0 = None
        self._stage_times: list[float] = []
        self._stage_t0 = self._t0
        self._written = -float("inf")
        self.record: dict = {}
        from compute.compiling import CompileNotice  # imports numba: not needed to watch runs (Display)

        self._compiling = CompileNotice(self.display.mark).start()

    def step(self, stage: int, pressure: float, phi: float, step: int, stage_steps: int) -> None:
        """After every accepted step."""
        now = time.monotonic()
        if self._steps0 is None:
            self._steps0 = step - 1
        elapsed = now - self._t0
        per_step = elapsed / max(step - self._steps0, 1)
        self.record = {"status": "running", "stage": stage, "stages": self.n_stages, "pressure": pressure,
                       "phi": phi, "step": step, "stage_steps": stage_steps, "seconds_per_step": per_step,
                       "elapsed": elapsed, "eta": self._eta(stage)}
        self.display.update(stage, self.text())
        if now - self._written >= self.interval:
            self._write()

    def stage_done(self) -> None:
        """After a stage's last step (the run's log says how it ended)."""
        now = time.monotonic()
        self._stage_times.append(now - self._stage_t0)
        self._stage_t0 = now
        if self.record:
            self.record["stage"] += 1
            self.record["eta"] = self._eta(self.record["stage"])
            self.display.update(self.record["stage"], self.text())
        self._write()

    def finish(self, status: str) -> None:
        """The run ended: ``status`` complete, incomplete or failed."""
        self._compiling.stop()
        if self.record:
            self.record.update(status=status, elapsed=time.monotonic() - self._t0, eta=0.0)
            self.display.mark(self.text())
        self._write()
        self.display.close()

    def _eta(self, stage: int) -> float | None:
        """Seconds left: the mean time of the finished stages times the stages from ``stage`` on."""
        if not self._stage_times:
            return None
        return sum(self._stage_times) / len(self._stage_times) * (self.n_stages - stage)

    def text(self) -> str:
        r = self.record
        if not r:
            return ""
        shown = min(r["stage"] + 1, r["stages"])
        return (f"stage {shown}/{r['stages']} P {r['pressure']:.4g} phi {r['phi']:.5f} step {r['step']} "
                f"{r['seconds_per_step']:.2g} s/step {_duration(r['elapsed'])} ETA {_duration(r['eta'])}"
                + (f" [{r['status']}]" if r["status"] != "running" else ""))

    def _write(self) -> None:
        if not self.record:
            return
        self._written = time.monotonic()
        files.write_text(self.out / PROGRESS, json.dumps(self.record))


def read_progress(out: str | Path) -> dict | None:
    """The last ``OUT/progress.json`` of a run, or None (not started, or unreadable mid-write)."""
    try:
        return json.loads((Path(out) / PROGRESS).read_text())
    except (OSError, ValueError):
        return None
