"""Target options (``abbe export --set``): every number has a range, every text a pattern
or choices, and any value either parses into its range or is refused with an
AbbeInputError naming ``--set NAME`` -- never another exception, never a value outside
the declared range, never a name that could break a file's syntax or leave OUT."""

from __future__ import annotations

import math
import re

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from abbe.errors import AbbeInputError
from abbe.exports import TARGETS, target_module
from abbe.exports.target import parse_options
from fuzzing.commands import OPTION_VALUES

SPECS = {t: target_module(t).OPTIONS for t in TARGETS}
NAME_SAFE = re.compile(r"[A-Za-z0-9_.+-]+")


@pytest.mark.parametrize("target", list(TARGETS))
def test_every_number_has_a_range_and_every_text_a_pattern(target):
    for name, o in SPECS[target].items():
        k = o.value_kind
        if k in ("int", "float"):
            assert o.lo is not None and o.hi is not None, (target, name)
            assert math.isfinite(o.lo) and math.isfinite(o.hi) and o.lo <= o.hi, (target, name)
        else:
            assert o.choices or o.pattern, (target, name)
        defaults = o.default.values() if o.kind == "axes" else [o.default]
        for d in defaults:  # the defaults themselves pass the checks
            o.check(str(d), f"--set {name}")


def _in_range(o, v) -> bool:
    if o.value_kind == "int":
        return isinstance(v, int) and o.lo <= int(v) <= o.hi
    if o.value_kind == "float":
        return isinstance(v, float) and math.isfinite(v) and o.lo <= v <= o.hi
    return isinstance(v, str) and (v in o.choices if o.choices else bool(NAME_SAFE.fullmatch(v)))


VALUES = st.one_of(st.sampled_from(OPTION_VALUES), st.text(max_size=12),
                   st.integers(-10**25, 10**25).map(str),
                   st.floats(allow_nan=True, allow_infinity=True).map(repr))


@settings(max_examples=400, derandomize=True, database=None, deadline=None,
          suppress_health_check=list(HealthCheck))
@given(st.sampled_from(sorted(TARGETS)), st.data(), VALUES, st.booleans())
def test_any_value_is_parsed_into_its_range_or_refused(target, data, value, per_axis):
    spec = SPECS[target]
    name = data.draw(st.sampled_from(sorted(spec)))
    o = spec[name]
    text = f"{data.draw(st.sampled_from('XYZ'))}={value}" if o.kind == "axes" and per_axis \
        else value
    try:
        got = parse_options(target, spec, [f"{name}={text}"])[name]
    except AbbeInputError as exc:
        assert exc.field is not None and exc.field.startswith(f"--set {name}"), str(exc)
        assert "\n" not in str(exc)
        return
    if o.kind == "axes":
        for v in got.values():  # kept as written; the value it stands for is in range
            if o.value_kind in ("int", "float"):
                x = float(v)
                assert math.isfinite(x) and o.lo <= x <= o.hi, (target, name, text)
            else:
                assert v in o.choices if o.choices else NAME_SAFE.fullmatch(v), (target, text)
    else:
        assert _in_range(o, got), (target, name, text, got)
