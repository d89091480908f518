"""The JSON a route writes itself never holds a number JSON cannot carry: a NaN or an infinity
that reaches it is written as null, as pydantic writes a response model's, and logged."""

from __future__ import annotations

import json
import logging

import pytest

from service.responses import FiniteJSONResponse


def test_a_number_json_cannot_carry_is_written_as_null_and_logged(
    caplog: pytest.LogCaptureFixture,
) -> None:
    content = {"values": [[1.5, float("inf")]], "mean": {"a/b": float("nan")}, "n": 2}
    with caplog.at_level(logging.ERROR, logger="service.responses"):
        body = FiniteJSONResponse(content).body
    assert isinstance(body, bytes)
    assert json.loads(body) == {"values": [[1.5, None]], "mean": {"a/b": None}, "n": 2}
    [record] = caplog.records
    assert record.getMessage() == (
        "an answer held 2 numbers JSON cannot carry, written as null: the first at #/values/0/1"
    )


def test_finite_answers_are_written_as_starlette_writes_them(
    caplog: pytest.LogCaptureFixture,
) -> None:
    content = {"é": [1e308, -0.0, 3], "ok": True}
    assert FiniteJSONResponse(content).body == '{"é":[1e+308,-0.0,3],"ok":true}'.encode()
    assert not caplog.records
