"""An ``inlined`` function is compiled once, linked into its callers and inlined there: its own
code is never optimised alone nor made machine code (its callers do both), and Python cannot
call it (there is nothing to call)."""

from __future__ import annotations

from typing import Any, cast

import numpy as np
import pytest
from numba import njit

from nanonav.engine.compiled import episodic, episodic_counted, inlined


@inlined
def _doubled_plus_one(x: Any, i: int) -> float:
    return float(x[i] * 2.0 + 1.0)


@inlined
def _summed(x: Any) -> float:
    total = 0.0
    for i in range(x.shape[0]):
        total += _doubled_plus_one(x, i)
    return total


@njit
def _outer(x: Any) -> float:
    return _summed(x) + 1.0


def test_an_inlined_function_runs_in_its_caller_and_has_no_code_of_its_own() -> None:
    x = np.arange(5.0)
    assert _outer(x) == sum(2.0 * v + 1.0 for v in x) + 1.0
    for function in (_summed, _doubled_plus_one):
        [compiled] = cast(Any, function).overloads.values()
        library = compiled.library
        assert type(library).__name__ == "_LinkedOnly"
        # nothing of it in the machine-code engine: no address for its function
        assert library.get_pointer_to_function(compiled.fndesc.llvm_func_name) == 0
    [outer] = cast(Any, _outer).overloads.values()
    assert outer.library.get_pointer_to_function(outer.fndesc.llvm_func_name) != 0
    with pytest.raises(TypeError, match="cannot be called from Python"):
        _summed(x)


@episodic
def _scaled(x: Any, by: float) -> None:
    for i in range(x.shape[0]):
        x[i] *= by


@episodic_counted
def _norm(x: Any) -> float:
    return float(np.sqrt((x * x).sum()))


@njit
def _scaled_norm(x: Any) -> float:
    _scaled(x, 2.0)
    return _norm(x)


def test_a_linked_function_is_optimised_in_its_callers_and_called_whole_from_python() -> None:
    """``episodic`` and ``episodic_counted``: a compiled caller links the function's code (no
    machine code of its own, so it is optimised once, with the caller's); Python calls a copy
    compiled whole, which computes the same."""
    x = np.arange(4.0)
    assert _scaled_norm(x) == pytest.approx(2.0 * np.sqrt(14.0))
    for function in (_scaled, _norm):
        [compiled] = cast(Any, function).overloads.values()
        assert type(compiled.library).__name__ == "_LinkedOnly"  # optimised by its caller
    y = np.arange(4.0)
    _scaled(y, 2.0)  # from Python: the whole copy
    assert y.tolist() == x.tolist()
    assert _norm(y) == _scaled_norm(np.arange(4.0))
    [whole] = cast(Any, _norm).whole.overloads.values()
    assert whole.library.get_pointer_to_function(whole.fndesc.llvm_func_name) != 0
