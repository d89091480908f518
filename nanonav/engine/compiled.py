"""How the engine's loops are compiled: ``uncounted``, numba without reference counting.

A counted function increments and decrements an array's reference count, an atomic call each,
for every view it makes and every member it takes from a NamedTuple, and a counted function
called from an uncounted loop pays them anew at each call. Measured: those calls were two
thirds of a step's time once, and later (from ``fields.place_sources`` alone, ten a step) a
sixth of the vector env's; so whatever runs each step or each episode is inlined into an
uncounted loop or is uncounted itself.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar, cast

from numba import njit

_F = TypeVar("_F", bound=Callable[..., Any])


def uncounted(function: _F) -> _F:
    """``njit`` without reference counting (numba's ``_nrt=False``, which its typed signature
    does not name). Nothing compiled so may allocate (numba refuses it if anything does, and an
    array copied into another may allocate: copy element by element), and its caller holds
    every array it views."""
    options: dict[str, Any] = {"cache": True, "error_model": "numpy", "_nrt": False}
    return cast(_F, njit(**options)(function))
