"""An ``inlined`` function is compiled once, linked into its callers and inlined there: its own
code is never optimised alone nor made machine code (its callers do both), and Python cannot
call it (there is nothing to call)."""

from __future__ import annotations

from typing import Any, cast

import numpy as np
import pytest
from numba import njit

from nanonav.engine.compiled import inlined


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
