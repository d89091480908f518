"""A generator's handle: compiled code rebuilt from it draws what the generator itself would,
from the same state."""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from nanonav.engine.compiled import uncounted
from nanonav.engine.generators import HANDLE_WORDS, generator_at, handle


@uncounted
def _draws(handles: NDArray[np.uint64], k: int, out: NDArray[np.float64]) -> None:
    rng = generator_at(handles, k)
    for i in range(out.shape[0]):
        out[i] = rng.random() if i % 2 else rng.standard_normal()


@njit(cache=True)
def _draws_direct(rng: np.random.Generator, out: NDArray[np.float64]) -> None:
    for i in range(out.shape[0]):
        out[i] = rng.random() if i % 2 else rng.standard_normal()


def test_a_rebuilt_generator_draws_as_the_generator_and_advances_it() -> None:
    ours, twin, other = (np.random.default_rng(7), np.random.default_rng(7),
                         np.random.default_rng(8))  # fmt: skip
    handles = np.stack([handle(other), handle(ours)])
    assert handles.shape == (2, HANDLE_WORDS)
    drawn = np.empty(11)
    expected = np.empty(11)
    _draws(handles, 1, drawn)
    _draws_direct(twin, expected)
    assert np.array_equal(drawn, expected)
    # the state drawn from is the generator's own: both go on from the same point
    assert ours.random() == twin.random()
    # and the other row is another generator
    _draws(handles, 0, drawn)
    assert not np.array_equal(drawn, expected)


def test_handles_of_distinct_generators_differ_in_their_state() -> None:
    first, second = np.random.default_rng(1), np.random.default_rng(1)  # both alive
    a, b = handle(first), handle(second)
    assert a[1] != b[1]  # each its own state
    assert a[4] == b[4]  # the same functions (PCG64's next_double)
