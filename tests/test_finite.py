"""A document made finite for JSON: NaN and infinities become null, where they were is told."""

from __future__ import annotations

import math

import numpy as np

from nanonav.finite import finite


def test_every_non_finite_number_becomes_none_and_its_place_is_told() -> None:
    found: list[str] = []
    document = {
        "a": [1.0, math.inf, (np.float64(-math.inf), 2)],
        "b/c~": math.nan,
        "n": 3,
        "s": "x",
    }
    assert finite(document, found) == {"a": [1.0, None, [None, 2]], "b/c~": None, "n": 3, "s": "x"}
    assert found == ["#/a/1", "#/a/2/0", "#/b~1c~0"]


def test_a_finite_document_comes_back_equal() -> None:
    document = {"x": [1e308, -0.0, 5e-324], "y": {"z": True, "w": None}}
    assert finite(document) == document
    assert finite(math.nan) is None
