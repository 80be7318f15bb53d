"""The strict number parser: ASCII decimal only, finite, in range; the column form agrees."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from abbe.errors import (
    AbbeInputError,
    check_int,
    check_number,
    parse_int,
    parse_int_column,
    parse_number,
    parse_number_column,
)

FUZZ = settings(max_examples=300, derandomize=True, database=None, deadline=None)


@pytest.mark.parametrize("text,value", [("1", 1.0), ("-2.5", -2.5), ("+.5", 0.5), ("5.", 5.0),
                                        ("1e3", 1000.0), ("-1.25E-2", -0.0125)])
def test_accepts_decimal(text, value):
    assert parse_number(text) == value


@pytest.mark.parametrize("text", ["nan", "inf", "-Infinity", "1e400", "1_0", "0x10", "\u0661",
                                  "\uff11", "1 0", " 1", "", ".", "e5", "1e", "--1", "1.2.3",
                                  "9" * 65, "²", "1,5", "true"])
def test_refuses_everything_else(text):
    with pytest.raises(AbbeInputError) as ei:
        parse_number(text, file="f.csv", line=3, field="x")
    e = ei.value
    assert (e.file, e.line, e.field) == ("f.csv", 3, "x")
    assert "\n" not in str(e)


def test_range_and_scale_are_in_the_message():
    with pytest.raises(AbbeInputError, match=r"in \[-100000, 100000\] um, got '1e300'"):
        parse_number("1e300", lo=-1e5, hi=1e5, unit="um")
    with pytest.raises(AbbeInputError, match=r"'2e11' = 2e\+08 um"):  # 2e11 nm
        parse_number("2e11", lo=-1e5, hi=1e5, unit="um", scale=1e-3)
    assert parse_number("1,5", decimal=",") == 1.5
    with pytest.raises(AbbeInputError, match="decimal mark"):
        parse_number("1.5", decimal=",")
    with pytest.raises(AbbeInputError, match="declare decimal"):
        parse_number("1,5")


def test_integers():
    assert parse_int("007", lo=1, hi=10) == 7
    for bad in ("1.0", "1e2", "1" * 23, "\u0663", "+", "0"):
        with pytest.raises(AbbeInputError):
            parse_int(bad, lo=1, hi=10 ** 6)


def test_values_from_toml_or_json():
    assert check_number(3, lo=0, hi=5) == 3.0
    for bad in (True, "1", None, float("nan"), float("inf"), 10 ** 5000, [1]):
        with pytest.raises(AbbeInputError) as ei:
            check_number(bad, lo=-1e9, hi=1e9)
        assert len(str(ei.value)) < 200  # a 5000-digit integer is not printed
    with pytest.raises(AbbeInputError, match=r"\(0, 1\]"):
        check_number(0, lo=0, hi=1, lo_open=True)
    assert check_int(4, lo=0, hi=7) == 4
    with pytest.raises(AbbeInputError):
        check_int(4.0, lo=0, hi=7)


@FUZZ
@given(st.floats(allow_nan=False, allow_infinity=False, min_value=-1e12, max_value=1e12))
def test_repr_round_trips(x):
    assert parse_number(repr(x)) == x
    assert parse_number(repr(x).replace(".", ","), decimal=",") == x


@FUZZ
@given(st.lists(st.one_of(st.from_regex(r"-?[0-9]{1,6}(\.[0-9]{0,4})?([eE]-?[0-9])?", fullmatch=True),
                          st.text(max_size=6)), min_size=1, max_size=20))
def test_column_form_agrees_with_the_scalar_form(cells):
    lines = np.arange(10, 10 + len(cells))

    def scalar():
        return [parse_number(c, file="f", line=int(n), field="c", lo=-1e9, hi=1e9)
                for c, n in zip(cells, lines)]
    try:
        want = scalar()
    except AbbeInputError as exc:
        with pytest.raises(AbbeInputError) as ei:
            parse_number_column(cells, lines, file="f", field="c", lo=-1e9, hi=1e9)
        assert str(ei.value) == str(exc)
        return
    got = parse_number_column(cells, lines, file="f", field="c", lo=-1e9, hi=1e9)
    assert got.tolist() == want


@FUZZ
@given(st.lists(st.text(alphabet="0123456789+-.e\u0663 x", min_size=0, max_size=5), min_size=1,
                max_size=12))
def test_int_column_agrees_with_the_scalar_form(cells):
    lines = np.arange(1, 1 + len(cells))
    try:
        want = [parse_int(c, file="f", line=int(n), field="run", lo=1, hi=100)
                for c, n in zip(cells, lines)]
    except AbbeInputError as exc:
        with pytest.raises(AbbeInputError) as ei:
            parse_int_column(cells, lines, file="f", field="run", lo=1, hi=100)
        assert str(ei.value) == str(exc)
        return
    assert parse_int_column(cells, lines, file="f", field="run", lo=1, hi=100).tolist() == want


@FUZZ
@given(st.text(min_size=1, max_size=12))
def test_anything_non_ascii_is_refused(t):
    if not t.isascii():
        with pytest.raises(AbbeInputError):
            parse_number(t)
    else:
        try:
            v = parse_number(t)
        except AbbeInputError:
            return
        assert math.isfinite(v) and float(t) == v
