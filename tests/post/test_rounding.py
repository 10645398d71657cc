"""The rounding rules of post.rounding, on values whose rounding is known by hand."""

import math

import pytest

from post import rounding


@pytest.mark.parametrize("seconds, text", [(915.9000000000001, "916"), (100.0, "100"), (3599.5, "3600"),
                                           (99.94, "99.9"), (12.34, "12.3"), (0.04123, "0.0412"),
                                           (0.0, "0"), (math.nan, "–"), (None, "–")])
def test_durations_whole_seconds_from_100_s_else_three_digits(seconds, text):
    assert rounding.duration(seconds) == text


@pytest.mark.parametrize("value, error, text", [
    (0.11718, 0.00483, "0.117 ± 0.005"),      # one digit of the error
    (0.98781, 0.00123, "0.9878 ± 0.0012"),    # leading 1: two digits
    (5.7512, 0.4, "5.8 ± 0.4"),
    (5.7512, 0.96, "5.8 ± 1.0"),              # 0.96 is 1 at one digit, a leading 1: two digits
    (0.7204, 0.0196, "0.72 ± 0.02"),          # 0.0196 is 0.02 at one digit: leading 2, one digit
    (1234.5, 37.0, "1230 ± 40"),              # above the decimal point
    (-0.0251, 0.0031, "-0.025 ± 0.003"),
])
def test_a_value_is_rounded_at_its_errors_first_significant_digits(value, error, text):
    assert rounding.with_error(value, error) == text


def test_without_an_error_the_fallback_rule():
    assert rounding.with_error(0.761234, math.nan, rounding.phi) == "0.7612"
    assert rounding.with_error(3.3333, 0.0, rounding.coordination) == "3.33"
    assert rounding.with_error(0.123456, math.inf) == "0.123"  # default: 3 significant digits
    assert rounding.with_error(math.nan, 0.01) == "–"
    assert rounding.with_error(5.1, 1e-15) == "5.1"  # an exact fit's round-off is not an error


def test_phi_coordination_and_significant():
    assert rounding.phi(0.81149999) == "0.8115" and rounding.phi(math.inf) == "–"
    assert rounding.coordination(3.0666) == "3.07"
    assert rounding.significant(0.000123456) == "0.000123" and rounding.significant(12345.0, 2) == "1.2e+04"
