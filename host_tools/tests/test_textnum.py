"""The tolerant text comparison used by the reproducibility tests can fail."""

from textnum import differences


def test_equal_and_last_digit_are_equivalent() -> None:
    assert differences('{"a": 9.675564196305142}', '{"a": 9.675564196305142}') == []
    assert differences('{"a": 9.675564196305142}', '{"a": 9.675564196305144}') == []
    assert differences("x,1.2345\n", "x,1.2346\n") == []           # one unit of the last digit
    assert differences("v = 1234567;", "v = 1234568;") == []       # integer rounding flip


def test_real_differences_are_found() -> None:
    assert differences("x,1.2345\n", "x,1.2348\n")                   # three units
    assert differences('{"a": 9.6755}', '{"b": 9.6755}')               # text
    assert differences("v = 1234567;", "v = 1234570;")               # integer off by 3
    assert differences("0x1F, 0x20", "0x1F, 0x21")                   # hex exactly
    assert differences("1.0e-3", "2.0e-3")
    assert differences("1, 2", "1, 2, 3")                            # extra field
