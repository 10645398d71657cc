"""No lab notebook in the code: the comments and strings of compute/, pre/ and post/ hold no
measured figures (durations, speed-ups, "% of", "measured 3 ...").

Why: such a figure describes one run of one version of the code and goes stale with the next
change. Measurements live in benchmarks/results/*.md, which a docstring cites by file name
(the reason for a choice stays in the docstring, its numbers in the results file). Physics
constants, tolerances, default values and equation references are not measurements and are
not matched.
"""

from __future__ import annotations

import io
import re
import tokenize
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("compute", "pre", "post")

_NUMBER = r"(?<![\w.:/-])\d+(?:\.\d+)?"
_RANGE = rf"{_NUMBER}(?:\s*[–-]\s*\d+(?:\.\d+)?)?"
PATTERNS = {
    # "46 s", "0.3 ms", "2–10 s steps", "50 µs", "43 min", "3 hours"; not "every 30 s" (a period
    # the code keeps, not a measurement) nor "h (s)".
    "duration": re.compile(rf"(?<!every ){_RANGE}\s?(?:s|ms|µs|us|min|h|hours?|minutes?|seconds?)(?![\w(])"),
    # "2.9x", "11.6× faster", "3 times", "several times faster"; not "2x2 blocks" nor a format
    # specification such as ":08x".
    "speed-up": re.compile(rf"{_NUMBER}[x×](?![\w\d])|{_NUMBER} times\b"
                           r"|\btimes (?:faster|slower|fewer|cheaper|quicker|shorter|longer)\b"),
    # "12 % of the run", "28 % shorter"
    "percent": re.compile(r"%\s+of\b|\d\s?%\s+(?:faster|slower|shorter|longer|less time|more time|fewer|more)\b"),
    # "measured 1.46 times", "measured: 0.4 s", "Measured on a 500-disk mixture"
    "measured": re.compile(r"\bmeasured:?\s+(?:(?:on|at|in|with|over)\s+)?(?:(?:a|an|the)\s+)?~?\d",
                           re.IGNORECASE),
}


def _text_tokens(source: str):
    """(first line, text) of every comment and string literal of ``source`` (f-strings' text
    parts included)."""
    kinds = {tokenize.COMMENT, tokenize.STRING}
    if hasattr(tokenize, "FSTRING_MIDDLE"):  # Python >= 3.12 splits f-strings
        kinds.add(tokenize.FSTRING_MIDDLE)
    for tok in tokenize.generate_tokens(io.StringIO(source).readline):
        if tok.type in kinds:
            yield tok.start[0], tok.string


def measured_figures(text: str) -> list[str]:
    """Names of the patterns that match one line of a comment or string."""
    return [name for name, pattern in PATTERNS.items() if pattern.search(text)]


def findings(root: Path = ROOT) -> list[str]:
    """``path:line: [patterns] text`` of every line of a comment or string in the packages'
    .py files that holds a measured figure."""
    out = []
    for package in PACKAGES:
        for path in sorted((root / package).rglob("*.py")):
            rel = path.relative_to(root).as_posix()
            for first, text in _text_tokens(path.read_text(encoding="utf-8")):
                for k, line in enumerate(text.splitlines()):
                    names = measured_figures(line)
                    if names:
                        out.append(f"{rel}:{first + k}: [{', '.join(names)}] {line.strip()}")
    return out


def test_no_measured_figures_in_code():
    found = findings()
    assert not found, ("measured figures in comments or docstrings; move them to "
                       "benchmarks/results/*.md and cite the file:\n" + "\n".join(found))


@pytest.mark.parametrize("line", [
    "step spent 46 s in ten such solves before its cut",
    "a contact update takes 0.3 ms",
    "Newton iterations, some 50 s of a run of 2–10 s steps",
    "about 50 µs here, against 2 µs with one thread",
    "complete, 1310 steps in 43 min",
    "the assembly is 2.9x faster",
    "11.6× faster than the scatter",
    "1.46–1.54 times faster than the scatter",
    "single particle 1.9-2.2 times fewer factorisations",
    "impulses 190 times the body's median",
    "several times faster per step on the rigid packings",
    "the contact solve is 61 % of the step",
    "the 1000-element disk's run 28 % shorter",
    "measured 1.46–1.54 times faster",
    "Measured on a 500-disk soft mixture",
    "good steps; measured on 30 steps of that mixture",
])
def test_patterns_catch_measured_figures(line):
    assert measured_figures(line)


@pytest.mark.parametrize("line", [
    "h (s) the time step",
    "a plain line every 30 s otherwise",
    "2x2 blocks, assembled per contact",
    "f\"{END_MARK} rows={rows} crc32={zlib.crc32(body):08x}\"",
    "within 1 % (the wall force balance)",
    "0.41 % less area for a 40-node boundary",
    "a ten times tighter test",
    "phi_tolerance = 1e-4, check_every = 20 steps",
    "Fits of the paper's laws to measured curves",
    "mesh size 0.955 x the boundary segment length",
    "Eq. 3: the measured K/E against (Z phi / 2 pi) K_p(phi)/E",
])
def test_patterns_leave_legitimate_text(line):
    assert not measured_figures(line)
