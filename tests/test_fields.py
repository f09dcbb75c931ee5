"""The settings files' validation helper (ipromp_pin/fields.py): known keys with a suggestion, ranges
with their bounds, unit and source, typed getters that refuse what is not of their type."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ipromp_pin.exceptions import PipelineError
from ipromp_pin.fields import Range, Table, did_you_mean, field_errors, float_array

ERROR = field_errors(PipelineError, "f.toml")


def _problem(fn) -> str:
    with pytest.raises(PipelineError) as exc:
        fn()
    msg = str(exc.value)
    assert msg.startswith("f.toml: ") and "\n" not in msg
    return msg


def test_a_near_miss_is_suggested_and_a_far_one_is_not():
    assert did_you_mean("speed_margn", ["speed_margin", "contact"]) == "; did you mean 'speed_margin'?"
    assert did_you_mean("ISO15066", ["iso15066"]) == "; did you mean 'iso15066'?"  # case ignored
    assert did_you_mean("zzz", ["speed_margin", "contact"]) == ""
    msg = _problem(lambda: Table({"contakt": "x"}, "iso15066", ERROR, ["contact", "speed_margin"]))
    known = "(known: contact, speed_margin)"
    assert msg == f"f.toml: field 'iso15066.contakt': unknown key; did you mean 'contact'? {known}"


def test_a_range_has_open_and_closed_bounds_and_refuses_nan():
    closed = Range(0.0, 1.0, "s", "why")
    half_open = Range(0.0, 1.0, "", "why", lo_open=True)
    assert closed.contains(0.0) and closed.contains(1.0) and not closed.contains(1.0 + 1e-12)
    assert not half_open.contains(0.0) and half_open.contains(1.0)
    assert not closed.contains(math.nan)
    assert closed.text() == "[0, 1] s" and half_open.text() == "(0, 1]"
    msg = _problem(lambda: closed.check(np.array([0.5, 2.0]), "a.b", ERROR))
    assert msg == "f.toml: field 'a.b': implausible value 2 s (plausible range [0, 1] s: why)"


@pytest.mark.parametrize(
    ("value", "problem"),
    [(True, "must be a number"), ("1", "must be a number"), (math.inf, "must be finite"), (5.0, "plausible")],
)
def test_a_number_is_a_finite_int_or_float_in_its_range(value, problem):
    table = Table({"x": value}, "t", ERROR, ["x"])
    msg = _problem(lambda: table.number("x", Range(0.0, 1.0, "m", "why")))
    assert msg.startswith("f.toml: field 't.x': ") and problem in msg
    assert Table({"x": 1}, "t", ERROR, ["x"]).number("x") == 1.0
    assert Table({}, "t", ERROR, ["x"]).number("x", None, 0.25) == 0.25


def test_a_vector_a_text_and_a_sub_table():
    table = Table({"v": [1, 2, 3], "s": 2.0, "k": "box", "sub": {"y": 1}}, "t", ERROR)
    np.testing.assert_array_equal(table.vector("v", 3), [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(table.vector("s", 3, scalar=True), [2.0, 2.0, 2.0])
    assert "a list of 2 numbers" in _problem(lambda: table.vector("v", 2))
    assert table.text("k", choices=["box", "sphere"]) == "box"
    assert "did you mean 'box'?" in _problem(
        lambda: Table({"k": "bx"}, "t", ERROR).text("k", choices=["box"])
    )
    assert "field 't.sub.y': unknown key (known: z)" in _problem(lambda: table.table("sub", ["z"]))
    assert "field 't.missing': missing" in _problem(lambda: table.table("missing", required=True))


def test_a_float_array_is_numeric_of_its_shape_non_empty_and_finite_unless_told():
    assert float_array([[1, 2, 3]], "a", 2, ERROR, last=3).shape == (1, 3)
    assert "'a': not a numeric array" in _problem(lambda: float_array([["x"]], "a", 2, ERROR))
    assert "expected 2 dimensions, got shape (3,)" in _problem(lambda: float_array([1, 2, 3], "a", 2, ERROR))
    assert "expected last dimension 4" in _problem(lambda: float_array([[1.0, 2.0]], "a", 2, ERROR, last=4))
    assert "is empty" in _problem(lambda: float_array(np.zeros((0, 3)), "a", 2, ERROR))
    assert "NaN or infinite" in _problem(lambda: float_array([np.nan], "a", 1, ERROR))
    assert np.isnan(float_array([np.nan, 1.0], "a", 1, ERROR, finite=False)[0])
