"""Numbers for people: how post rounds what a reader sees (summary.md, markdown tables, figure
labels, messages). CSV and JSON files keep every digit; these rules are for text only.

- a duration in seconds: whole seconds from a hundred up, three significant digits below (915.9 is
  "916", 12.34 is "12.3");
- a value with its standard error (or its scatter): the error to one significant digit, two when
  that digit is 1 (one digit would move such an error by up to a third), and the value to the same
  decimal place: 0.11718 ± 0.00483 is "0.117 ± 0.005", 0.9878 ± 0.0012 is "0.9878 ± 0.0012";
- a packing fraction φ: four decimals (the stages' equilibrium criteria hold φ to about 1e-4);
- a coordination number Z: two decimals (in a box of 30 disks one contact moves Z by 0.067);
- any other measured quantity: three significant digits.

A missing value (None, NaN, ±inf) is written "–".
"""

from __future__ import annotations

import math

MISSING = "–"
NEGLIGIBLE = 1e-9  # relative error below which a value is written as if it had none


def _finite(x) -> bool:
    return x is not None and math.isfinite(float(x))


def significant(x, digits: int = 3) -> str:
    """x to ``digits`` significant digits ("0.0123", "1.23e+04")."""
    return f"{float(x):.{digits}g}" if _finite(x) else MISSING


def decimals(x, places: int) -> str:
    """x with ``places`` decimals."""
    return f"{float(x):.{places}f}" if _finite(x) else MISSING


def duration(seconds) -> str:
    """A duration in seconds, without the unit: whole seconds from a hundred up, else 3 significant
    digits (915.9000000000001 -> "916", 12.34 -> "12.3")."""
    if not _finite(seconds):
        return MISSING
    return f"{float(seconds):.0f}" if abs(float(seconds)) >= 100 else significant(seconds, 3)


def phi(x) -> str:
    """A packing fraction, 4 decimals."""
    return decimals(x, 4)


def coordination(x) -> str:
    """A coordination number, 2 decimals."""
    return decimals(x, 2)


def error_places(error: float) -> int:
    """The decimal place (digits after the point; negative for tens, hundreds...) to which an error
    > 0 is rounded: its first significant digit, its first two when that digit is 1."""
    exponent = math.floor(math.log10(error))
    leading = round(error / 10.0**exponent, 1)  # 9.96 rounds up to 10: one digit of the next decade
    if leading >= 10.0:
        exponent, leading = exponent + 1, leading / 10.0
    return -exponent + (1 if leading < 2.0 else 0)


def with_error(value, error, otherwise=significant) -> str:
    """"value ± error" both rounded at the error's place (module docstring); ``otherwise(value)``
    when the error is missing, not positive (a fit without covariance, a single seed) or below
    ``NEGLIGIBLE`` times the value (an exact fit: its error is round-off)."""
    if not _finite(value):
        return MISSING
    if not _finite(error) or float(error) <= NEGLIGIBLE * abs(float(value)):
        return otherwise(value)
    places = error_places(float(error))
    if places >= 0:
        return f"{float(value):.{places}f} ± {float(error):.{places}f}"
    step = 10.0**-places
    return f"{round(float(value) / step) * step:.0f} ± {round(float(error) / step) * step:.0f}"
