"""quadnodes.units: unit names, conversion and lengths written as text."""

import pytest
from hypothesis import given
from hypothesis import strategies as st

from quadnodes.errors import InputError
from quadnodes.units import UNITS, is_length_text, parse_length, to_unit


@given(st.floats(-1e6, 1e6), st.sampled_from(sorted(UNITS)), st.sampled_from(sorted(UNITS)))
def test_conversion_round_trips(x, a, b):
    assert to_unit(to_unit(x, a, b), b, a) == pytest.approx(x, rel=1e-12, abs=1e-9)


@pytest.mark.parametrize(
    ("text", "target", "expected"),
    [("2 mm", "mm", 2.0), ("2mm", "m", 0.002), (" 1.5e3 mm ", "m", 1.5), ("1 in", "mm", 25.4), ("-3 cm", "mm", -30.0)],
)
def test_parse_length_text(text, target, expected):
    assert is_length_text(text)
    assert parse_length(text, target) == pytest.approx(expected)


@pytest.mark.parametrize("bad", ["2", "two mm", "2 furlong", "", None, True, float("nan"), [2]])
def test_parse_length_refuses_with_the_name(bad):
    with pytest.raises(InputError, match="planar_tolerance"):
        parse_length(bad, "mm", "planar_tolerance")


@pytest.mark.parametrize("text", ["1e400 mm", "1e308 ft", "-1e400 m"])
def test_a_length_too_large_for_a_float_is_refused(text):
    # '1e400 mm' became inf and passed as a planar_tolerance (every panel 'planar'); 'inf mm' was refused
    with pytest.raises(InputError, match=rf"^planar_tolerance: {text!r} is not a finite length in mm$"):
        parse_length(text, "mm", "planar_tolerance")
    assert parse_length("1e300 mm", "mm") == 1e300
