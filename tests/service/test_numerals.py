"""Numbers read from unvalidated text: one spelling each, ASCII digits only."""

from __future__ import annotations

import pytest

from nanonav.scenario import MAX_EXACT_INT
from service.numerals import positive_int


@pytest.mark.parametrize(
    ("text", "value"),
    [("1", 1), ("42", 42), ("1000", 1000), (str(MAX_EXACT_INT), MAX_EXACT_INT)],
)
def test_a_canonical_positive_integer_is_read(text: str, value: int) -> None:
    assert positive_int(text) == value


@pytest.mark.parametrize(
    "text",
    [
        "", "0", "00", "01", "007", "+1", "-1", " 1", "1 ", "1.0", "1_000", "0x1", "1e3",
        "\u00b2",  # superscript two: str.isdigit takes it, int refuses it
        "\u2460",  # circled one
        "\u0661",  # Arabic-Indic one: int reads it as 1
        "\uff11",  # fullwidth one
        "1\u0660",
        str(MAX_EXACT_INT + 1),
        "9" * 5000,  # past int's limit on digits, and past any id
    ],
)  # fmt: skip
def test_anything_else_is_not_a_number(text: str) -> None:
    assert positive_int(text) is None


def test_the_maximum_bounds_the_value_and_the_length() -> None:
    assert positive_int("65535", maximum=65535) == 65535
    assert positive_int("65536", maximum=65535) is None
    assert positive_int("100000", maximum=65535) is None
