"""NumPy generators handed to compiled code as numbers, so that a loop over many worlds draws from
each world's own generator without counting references.

Numba hands a ``np.random.Generator`` to compiled code as its bit generator's state and
functions, plus a counted reference to the Python object. Many generators, held in a typed
list of tuples, cost the vector env two atomic calls a world a step to take out (measured:
about half of a 1,000-world call's own overhead of 27 us), and a tuple of them is passed
world by world, chunk by chunk. A *handle* is the same state and functions as plain numbers,
``HANDLE_WORDS`` of them in a row of an array: ``generator_at`` rebuilds the generator from its
row, without a reference. Whoever makes a handle keeps its generator alive while it is used.
"""

from __future__ import annotations

import ctypes
from typing import Any

import numpy as np

# first: numba's cache is pointed at the engine's folder before this module compiles
from nanonav.engine import compiled  # noqa: F401  # isort: skip
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic
from numpy.typing import NDArray

HANDLE_WORDS = 6  # state address, state, next_uint64, next_uint32, next_double, bit generator
_GENERATOR = types.NumPyRandomGeneratorType("NumPyRandomGeneratorType")
_BIT_GENERATOR = types.NumPyRandomBitGeneratorType("bit_generator")
# numba's code-generation helpers, untyped
_struct: Any = cgutils.create_struct_proxy
_null: Any = cgutils.get_null_value


def handle(generator: np.random.Generator) -> NDArray[np.uint64]:
    """``generator``'s handle, read as numba reads a generator it is handed."""
    bound = generator.bit_generator.ctypes

    def address(function: Any) -> int:
        return int(ctypes.cast(function, ctypes.c_void_p).value or 0)

    return np.array(
        [
            bound.state_address,
            bound.state.value,
            address(bound.next_uint64),
            address(bound.next_uint32),
            address(bound.next_double),
            bound.bit_generator.value,
        ],
        dtype=np.uint64,
    )


@intrinsic
def _rebuilt(
    typingctx: Any, state_address: Any, state: Any, next_uint64: Any, next_uint32: Any,
    next_double: Any, bit_generator: Any,
) -> Any:  # fmt: skip
    """A generator from its handle's words, holding no reference (its meminfo and Python
    object are null, so counting it in or out does nothing)."""
    signature = _GENERATOR(types.uint64, types.uint64, types.uint64, types.uint64, types.uint64,
                           types.uint64)  # fmt: skip

    def codegen(context: Any, builder: Any, sig: Any, args: Any) -> Any:
        bits = _struct(_BIT_GENERATOR)(context, builder)
        bits.parent = _null(bits.parent.type)
        bits.state_address = args[0]
        bits.state = args[1]
        bits.fnptr_next_uint64 = args[2]
        bits.fnptr_next_uint32 = args[3]
        bits.fnptr_next_double = args[4]
        bits.bit_generator = args[5]
        generator = _struct(_GENERATOR)(context, builder)
        generator.bit_generator = bits._getvalue()
        generator.meminfo = _null(generator.meminfo.type)
        generator.parent = _null(generator.parent.type)
        return generator._getvalue()

    return signature, codegen


@njit(cache=True, error_model="numpy", inline="always")
def generator_at(handles: NDArray[np.uint64], k: int) -> np.random.Generator:
    """The generator whose handle is ``handles[k]``."""
    rebuilt: Any = _rebuilt  # its typing signature is numba's, not its call's
    generator: np.random.Generator = rebuilt(
        handles[k, 0], handles[k, 1], handles[k, 2], handles[k, 3], handles[k, 4], handles[k, 5]
    )
    return generator
