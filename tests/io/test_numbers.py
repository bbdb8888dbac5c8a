"""``segadeform.io.numbers``: text files' numbers as the formats write them, not as Python's float() reads."""

from __future__ import annotations

import math

import pytest

from segadeform.io.numbers import integer, number


@pytest.mark.parametrize(
    "token, value",
    [("0", 0.0), ("-1.5", -1.5), ("+2", 2.0), (".5", 0.5), ("5.", 5.0), ("2e-3", 0.002), ("1E+2", 100.0)],
)
def test_numbers_files_write_are_read(token, value):
    assert number(token) == value


def test_non_finite_words_are_left_to_the_readers():
    # every reader refuses them with its own "not finite"; the token itself is a number's spelling
    assert math.isnan(number("nan")) and number("-inf") == -math.inf and number("Infinity") == math.inf


@pytest.mark.parametrize("token", ["0.15_9", "1_000", "\u0661", "\uff11", " 1", "1 ", "1\u00a0", "", "x", "0x10"])
def test_what_float_reads_and_no_file_writes_is_refused(token):
    with pytest.raises(ValueError):
        number(token)


@pytest.mark.parametrize("token, value", [("12", 12), ("-3", -3), ("+4", 4), ("007", 7)])
def test_integers(token, value):
    assert integer(token) == value


@pytest.mark.parametrize("token", ["1_0", "\u0661\u0662", " 3", "3.0", "", "1e3"])
def test_integers_refused(token):
    with pytest.raises(ValueError):
        integer(token)
