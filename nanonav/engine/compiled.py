"""How the engine's loops are compiled: ``uncounted``, numba without reference counting;
``episodic``, the same linked into its callers; and ``inlined``, compiled once and inlined by
LLVM into every caller.

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
as fast to run, ``benchmarks/first_start.py``). An inlined function's own code is only linked
(``_LinkedOnly``): numba would optimise it with all it calls, then make it machine code, at
every level of the calls, where the function Python calls optimises and compiles it all once.
What runs once an episode or once a call, from compiled code only (``episodic``), is linked
into its callers the same way and optimised there (``linked``), not inlined by force; Python's
calls to it (the tests') run a copy compiled whole (``CalledWhole``). What runs for each robot
and is not inlined stays ``uncounted``, optimised alone and again in its callers: linked only,
it ran about 5 % slower.
A numba-inlined function remains where the inlined code must take its caller's floating-point
flags (``fields.sample`` in ``sample_many``, whose contraction the field's digests hold) or
returns what only an inlined call may (``generators.generator_at``).

A constant argument (``f(p, sim, 0)``, ``f(p, sim, True)``) would compile the callee again for
that constant (numba specialises on literals); callers pass variables, or ``int(0)`` and
``bool(True)``, which numba types as plain numbers.

What numba compiles is kept on disk (``cache=True``) under a folder named by a digest of
everything it was compiled from (``compiled_from``): every source of the engine and the
scenario, and the versions of Python, numba, llvmlite and numpy, and the processor. Numba's own
check looks at a function's file alone, so that a change to a function it calls from another
file left the old machine code running; with the digest, any change to the engine compiles it
anew, and the folders of other digests in the tree are removed.
"""

from __future__ import annotations

import hashlib
import os
import platform
import shutil
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar, cast

import llvmlite
import numba
import numpy as np
from llvmlite import binding as llvm
from numba import njit
from numba.core import config
from numba.core.codegen import JITCodeLibrary
from numba.core.compiler import CompilerBase, DefaultPassBuilder
from numba.core.compiler_machinery import LoweringPass, register_pass
from numba.core.registry import CPUDispatcher
from numba.core.typed_passes import AnnotateTypes

_F = TypeVar("_F", bound=Callable[..., Any])
ENGINE = Path(__file__).resolve().parent
# The sources compiled code depends on: the engine's, and the scenario's (the engine's only
# import of the rest of NanoNav)
SOURCES = (ENGINE, ENGINE.parent / "scenario", ENGINE.parent / "physics.py")
CACHE_PREFIX = "compiled-"


def compiled_from() -> str:
    """A digest of everything the engine's machine code is compiled from."""
    digest = hashlib.sha256()
    files = sorted(
        path for source in SOURCES
        for path in (source.rglob("*.py") if source.is_dir() else [source])
    )  # fmt: skip
    for path in files:
        digest.update(path.relative_to(ENGINE.parent).as_posix().encode() + b"\0")
        digest.update(path.read_bytes())
    host = llvm.get_host_cpu_name() + llvm.get_host_cpu_features().flatten()
    for part in (sys.version, numba.__version__, llvmlite.__version__, np.__version__,
                 platform.machine(), host):  # fmt: skip
        digest.update(part.encode() + b"\0")
    return digest.hexdigest()[:16]


def keep_compiled_code() -> Path:
    """Point numba's cache at the folder of this engine's digest (under ``NUMBA_CACHE_DIR``
    if it is set, else in the engine's ``__pycache__``, where the folders of other digests
    are removed); the folder. Called before any engine function is decorated."""
    given = os.environ.get("NUMBA_CACHE_DIR")
    base = Path(given) if given else ENGINE / "__pycache__"
    folder = base / f"{CACHE_PREFIX}{compiled_from()}"
    config.CACHE_DIR = str(folder)  # type: ignore[attr-defined]
    if not given and base.is_dir():
        for old in base.glob(f"{CACHE_PREFIX}*"):
            if old != folder:
                shutil.rmtree(old, ignore_errors=True)
    return folder


CACHE = keep_compiled_code()


def in_cache(function: Any) -> bool:
    """Whether numba's cache on disk holds machine code of the compiled engine function
    ``function``: if not, its first call compiles it (a minute for the whole engine), and
    whoever waits should be told."""
    python = function.py_func
    stem = f"{python.__module__.rsplit('.', 1)[-1]}.{python.__qualname__}-"
    # numba keeps each source folder's code in a folder of its own under the cache's
    return any(CACHE.rglob(f"{stem}*.nbi"))


def uncounted(function: _F) -> _F:
    """``njit`` without reference counting (numba's ``_nrt=False``, which its typed signature
    does not name). Nothing compiled so may allocate (numba refuses it if anything does, and an
    array copied into another may allocate: copy element by element), and its caller holds
    every array it views."""
    options: dict[str, Any] = {"cache": True, "error_model": "numpy", "_nrt": False}
    return cast(_F, njit(**options)(function))


def episodic(function: _F) -> _F:
    """``uncounted``, for what runs once an episode or a run, from compiled code: its compiled
    callers link its code and optimise it once with theirs (``linked``); called from Python
    (the tests do), a whole compiled copy of it runs."""
    return linked(error_model="numpy", _nrt=False)(function)


def episodic_counted(function: _F) -> _F:
    """``episodic`` with reference counting."""
    return linked(error_model="numpy")(function)


def linked(**options: Any) -> Callable[[_F], _F]:
    """A decorator: the function compiled under numba's ``options``, its code linked into its
    compiled callers and optimised there, once, with theirs (not inlined by force: LLVM
    decides), and compiled whole, kept on disk, for calls from Python (``CalledWhole``).
    Numba made machine code of each such function and optimised it anew in every caller."""

    def decorate(function: _F) -> _F:
        only = {**options, "no_cpython_wrapper": True, "pipeline_class": _LinkOnlyCompiler}
        dispatcher = njit(**only)(function)
        dispatcher.__class__ = CalledWhole
        dispatcher.whole_options = {**options, "cache": True}
        return cast(_F, dispatcher)

    return decorate


class CalledWhole(CPUDispatcher):
    """A function whose compiled callers link its code (it has no machine code of its own,
    and no wrapper for Python); a call from Python runs a copy compiled whole, made at the
    first such call."""

    whole_options: dict[str, Any]

    @property
    def whole(self) -> CPUDispatcher:
        """The copy compiled whole, for Python's calls."""
        found = self.__dict__.get("_whole")
        if found is None:
            found = self.__dict__["_whole"] = njit(**self.whole_options)(self.py_func)
        return cast(CPUDispatcher, found)

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        return self.whole(*args, **kwargs)


class CompiledOnly(CPUDispatcher):
    """A function compiled without a wrapper for Python: called from Python it is refused
    (without a wrapper, numba would jump to no code and crash the process)."""

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        raise TypeError(
            f"{self.py_func.__qualname__} is inlined into compiled code and cannot be called "
            "from Python: compile it with compiled.inlined_callable"
        )


class _LinkedOnly(JITCodeLibrary):
    """The code of a function that only compiled callers inline: numba's library would
    optimise it with everything it calls and make it machine code, which its callers do again
    once it is inlined (at every level of the calls: the optimising repeated was most of a
    step's compile). Here it is linked, not optimised beyond numba's function passes, and
    never made machine code; no cache keeps it (it has no object code to keep)."""

    @property
    def codegen(self) -> Any:
        """numba's codegen, but for the environment it would set in the machine code."""
        return _WithoutEnvironment(self._codegen)

    def _optimize_final_module(self) -> None:
        """Left to the caller that is called from Python, once everything is inlined."""

    def _finalize_final_module(self) -> None:
        """Ready to be linked, not added to the machine-code engine."""
        self._finalize_dynamic_globals()  # type: ignore[no-untyped-call]
        self._verify_declare_only_symbols()  # type: ignore[no-untyped-call]
        self._finalized = True


class _WithoutEnvironment:
    """A codegen whose ``set_env`` does nothing: a ``_LinkedOnly`` function has no machine
    code of its own to set it in (inlined, it runs in its callers' code, which are set)."""

    def __init__(self, codegen: Any) -> None:
        self._codegen = codegen

    def set_env(self, name: str, environment: Any) -> None:
        """Nothing to set."""

    def __getattr__(self, name: str) -> Any:
        return getattr(self._codegen, name)


@register_pass(mutates_CFG=False, analysis_only=False)  # type: ignore[no-untyped-call]
class _LinkOnly(LoweringPass):
    """Lowers into a ``_LinkedOnly`` library."""

    _name = "nanonav_link_only"

    def __init__(self) -> None:
        LoweringPass.__init__(self)  # type: ignore[no-untyped-call]

    def run_pass(self, state: Any) -> bool:
        codegen, name = state.targetctx.codegen(), state.func_id.func_qualname
        state.library = _LinkedOnly(codegen, name)  # type: ignore[no-untyped-call]
        state.library.enable_object_caching()
        return True


class _LinkOnlyCompiler(CompilerBase):
    """numba's nopython pipeline, lowering into a ``_LinkedOnly`` library."""

    def define_pipelines(self) -> list[Any]:
        build = DefaultPassBuilder.define_nopython_pipeline
        pipeline = build(self.state)  # type: ignore[no-untyped-call]
        pipeline.add_pass_after(_LinkOnly, AnnotateTypes)
        pipeline.finalize()
        return [pipeline]


def inlined(function: _F) -> _F:
    """``uncounted``, and inlined into every compiled caller by LLVM (its ``alwaysinline``:
    numba's ``forceinline``): compiled and typed once, whatever its callers, and without the
    wrapper that lets Python call it (which costs its compile a sixth)."""
    options: dict[str, Any] = {"error_model": "numpy", "_nrt": False, "forceinline": True,
                               "no_cpython_wrapper": True,
                               "pipeline_class": _LinkOnlyCompiler}  # fmt: skip
    dispatcher = njit(**options)(function)
    dispatcher.__class__ = CompiledOnly
    return cast(_F, dispatcher)


def inlined_callable(function: _F) -> _F:
    """``inlined``, and callable from Python too (the tests and the benchmarks call it)."""
    options: dict[str, Any] = {"cache": True, "error_model": "numpy", "_nrt": False,
                               "forceinline": True}  # fmt: skip
    return cast(_F, njit(**options)(function))
