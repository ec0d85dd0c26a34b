"""How numbers are shown to people (rivercal._format): a value to its unit's resolution, σ never shown as a
false zero, level errors in cm, counted nouns."""

from __future__ import annotations

import math

import pytest

from rivercal._format import format_cm, format_std, format_value, plural


@pytest.mark.parametrize(("value", "unit", "text"), [
    (-1.476e-05, "m", "0.00"),  # a crest shift of 0.015 mm is no shift: never "-1.476e-05"
    (-0.00004, "m", "0.00"),  # never "-0.00"
    (-0.0046, "m", "0.00"),  # rounds to zero, without a sign
    (-0.0062, "m", "-0.01"),
    (10.4549, "m AD", "10.45"),
    (24.349, "m^(1/3)/s", "24.3"),
    (0.5, "-", "0.50"),
    (3.14159, "m³/s", "3.14"),
    (1234.5678, "furlong", "1234.568"),
    (math.nan, "m", "–"),
    (None, "m", "–"),
])
def test_a_value_is_shown_to_the_resolution_of_its_unit(value, unit, text) -> None:
    assert format_value(value, unit) == text


def test_a_value_with_its_unit() -> None:
    assert format_value(-1.476e-05, "m", with_unit=True) == "0.00 m"
    assert format_value(0.42, "-", with_unit=True) == "0.42"


def test_a_small_sigma_is_never_shown_as_zero() -> None:
    assert format_std(0.002, "m") == "< 0.01"
    assert format_std(0.0, "m") == "0.00"
    assert format_std(0.12, "m^(1/3)/s", with_unit=True) == "0.1 m^(1/3)/s"
    assert format_std(0.04, "m^(1/3)/s") == "< 0.1"


def test_level_errors_are_shown_in_cm() -> None:
    assert format_cm(0.0346) == "3.5 cm"
    assert format_cm(-0.0345, signed=True).startswith("-3.")
    assert format_cm(0.021, signed=True) == "+2.1 cm"
    assert format_cm(-0.0004, signed=True) == "+0.0 cm"  # no "-0.0"
    assert format_cm(None) == "–"


@pytest.mark.parametrize(("n", "noun", "nouns", "text"), [
    (1, "weir", None, "1 weir"), (13, "weir", None, "13 weirs"), (1, "boundary", None, "1 boundary"),
    (2, "boundary", None, "2 boundaries"), (0, "day", None, "0 days"), (3, "series", "series", "3 series"),
    (2, "quantity", None, "2 quantities"), (2, "branch", None, "2 branches"), (1, "branch", None, "1 branch"),
    (3, "universal weir", None, "3 universal weirs"), (2, "pass", None, "2 passes"),
])
def test_a_count_takes_the_right_number_of_its_noun(n, noun, nouns, text) -> None:
    assert plural(n, noun, nouns) == text
