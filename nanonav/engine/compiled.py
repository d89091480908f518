"""How the engine's loops are compiled: ``uncounted``, numba without reference counting, and
``inlined``, compiled once and inlined by LLVM into every caller.

A counted function increments and decrements an array's reference count, an atomic call each,
for every view it makes and every member it takes from a NamedTuple, and a counted function
called from an uncounted loop pays them anew at each call. Measured: those calls were two
thirds of a step's time once, and later (from ``fields.place_sources`` alone, ten a step) a
sixth of the vector env's; so whatever runs each step or each episode is inlined into an
uncounted loop or is uncounted itself.

A call that is not inlined passes the world (``phases.Sim``: some sixty arrays, each a pointer,
its shape and strides) and the parameters (about seventy numbers) argument by argument: made
for every robot, such calls ran the engine five times slower. So the phases are inlined, and
by LLVM (``inlined``), not by numba (``inline="always"``): numba copied and retyped a
function's whole body at each place it was inlined, and nested, the copies were most of the
engine's first compile (308 s and 3.2 GB for ``simulate``; 59 s and 0.7 GB inlined by LLVM,
as fast to run, ``benchmarks/first_start.py``). A numba-inlined function remains where the
inlined code must take its caller's floating-point flags (``fields.sample`` in
``sample_many``, whose contraction the field's digests hold) or returns what only an inlined
call may (``generators.generator_at``).

A constant argument (``f(p, sim, 0)``) would compile the callee again for that constant (numba
specialises on literals); callers pass variables.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar, cast

from numba import njit
from numba.core.registry import CPUDispatcher

_F = TypeVar("_F", bound=Callable[..., Any])


def uncounted(function: _F) -> _F:
    """``njit`` without reference counting (numba's ``_nrt=False``, which its typed signature
    does not name). Nothing compiled so may allocate (numba refuses it if anything does, and an
    array copied into another may allocate: copy element by element), and its caller holds
    every array it views."""
    options: dict[str, Any] = {"cache": True, "error_model": "numpy", "_nrt": False}
    return cast(_F, njit(**options)(function))


class CompiledOnly(CPUDispatcher):
    """A function compiled without a wrapper for Python: called from Python it is refused
    (without a wrapper, numba would jump to no code and crash the process)."""

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        raise TypeError(
            f"{self.py_func.__qualname__} is inlined into compiled code and cannot be called "
            "from Python: compile it with compiled.inlined_callable"
        )


def inlined(function: _F) -> _F:
    """``uncounted``, and inlined into every compiled caller by LLVM (its ``alwaysinline``:
    numba's ``forceinline``): compiled and typed once, whatever its callers, and without the
    wrapper that lets Python call it (which costs its compile a sixth)."""
    options: dict[str, Any] = {"cache": True, "error_model": "numpy", "_nrt": False,
                               "forceinline": True, "no_cpython_wrapper": True}  # fmt: skip
    dispatcher = njit(**options)(function)
    dispatcher.__class__ = CompiledOnly
    return cast(_F, dispatcher)


def inlined_callable(function: _F) -> _F:
    """``inlined``, and callable from Python too (the tests and the benchmarks call it)."""
    options: dict[str, Any] = {"cache": True, "error_model": "numpy", "_nrt": False,
                               "forceinline": True}  # fmt: skip
    return cast(_F, njit(**options)(function))
