"""A network sent as a policy runs in a process of its own, with limits: whatever its model does
to ONNX Runtime (a SIGFPE, a hang, an allocation of gigabytes), the process that asked, the API
or a worker, goes on.

``Sandbox`` starts the process (``python -m nanonav.rl.sandbox``), hands it a model to check
and load (``load``) and then observations to decide for (``run``), and waits for each answer
with a deadline, asking the caller's ``keep_going`` every ``POLL_S`` whether to wait on: a job
cancelled or past its time limit stops within a call. A process that dies, overruns its time,
or answers what it was not asked is killed and reported (``SandboxFailed``); a model that the
checks refuse is ``InvalidModel``, as it would be anywhere.

The process starts in an empty folder of its own (removed when it ends; its home, where ONNX
Runtime writes a device id as it is imported, is another), with an environment
made from nothing but ``CARRIED`` of its parent's: a file a model names resolves to nothing
there, and no key or secret of the API's or the worker's is there to be read. The model
reaches it as bytes, and it alone parses it (the API reads only its size).

The process sets its own limits, after its imports and before it reads a byte of the model:
its address space (``RLIMIT_AS``), its CPU seconds (``RLIMIT_CPU``: SIGXCPU, then SIGKILL), no
core dump, no file written; it dies with the thread that started it (``PR_SET_PDEATHSIG``, on
Linux), and is in a session of its own, so a terminal's Ctrl-C reaches its parent alone. It
runs ONNX Runtime on one thread. Messages both ways (``framed``) are a fixed binary header,
a text (JSON, or a message in words) and raw arrays (numpy's own bytes, never a pickle), on
its standard input and output.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import select
import shutil
import signal
import struct
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, NoReturn

import numpy as np
from numpy.typing import NDArray

from nanonav.children import die_with_parent
from nanonav.rl.graph import InvalidModel, ModelInfo

# How often a wait asks ``keep_going``, seconds
POLL_S = 0.1
# Extra CPU seconds past the soft limit before the kernel kills the process outright
CPU_GRACE_S = 2
# The most bytes one read of a pipe takes (its buffer's size: a larger read costs an allocation)
READ_BYTES = 1 << 16
# A message: its kind, its arrays' count, the sender's CPU seconds and largest resident memory
# so far, its text's length; then the text, each array's dtype code and rank and shape, and
# each array's bytes
HEAD = struct.Struct("<cBdQI")
ARRAY = struct.Struct("<cB")
DIM = struct.Struct("<Q")
DTYPES: dict[bytes, np.dtype[Any]] = {
    b"f": np.dtype("<f4"),
    b"q": np.dtype("<i8"),
    b"i": np.dtype("<i4"),
    b"B": np.dtype("u1"),
}
CODES = {dtype: code for code, dtype in DTYPES.items()}
MAX_RANK = 8
# The largest text, and the largest arrays, the parent reads from the process
MAX_TEXT_BYTES = 1 << 16
MAX_ANSWER_BYTES = 1 << 30
# Kinds: asked (read a model's labels, load a model, run it) and answered (its info or
# labels, arrays, a refusal, an error)
LABELS, LOAD, RUN = b"M", b"L", b"R"
INFO, ARRAYS, REFUSED, ERROR = b"I", b"A", b"X", b"E"


# What the process is given of its parent's environment: where programs are, the locale, and
# OpenBLAS's processor settings (numpy computes wrongly on some processors without them).
# Nothing else: the API's and the worker's keys and secrets live in theirs.
CARRIED = ("PATH", "LANG", "LC_ALL", "OPENBLAS_CORETYPE", "OPENBLAS_L2_SIZE")
# Where ``nanonav`` is imported from, for the process's ``-m nanonav.rl.sandbox``
SOURCE_ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def bare_environment(home: str) -> dict[str, str]:
    """The whole environment of a network's process: ``CARRIED`` of this one's, one thread for
    ONNX Runtime, and ``home`` (a folder of its own, where ONNX Runtime writes its device id
    as it is imported) as its home and temporary folder."""
    env = {name: os.environ[name] for name in CARRIED if name in os.environ}
    env.update(
        HOME=home,
        TMPDIR=home,
        OMP_NUM_THREADS="1",
        PYTHONDONTWRITEBYTECODE="1",
        PYTHONPATH=SOURCE_ROOT,
    )
    return env


class SandboxFailed(RuntimeError):
    """The network's process died, ran past its time or memory, or answered nonsense; the
    message says which, in words for the person who sent the network."""


class Interrupted(RuntimeError):
    """The caller's ``keep_going`` said stop while the network ran: its process was killed."""


@dataclass
class Message:
    """One message of the protocol, either way."""

    kind: bytes
    text: str = ""
    arrays: list[NDArray[Any]] = field(default_factory=list)
    cpu_s: float = 0.0
    max_rss_bytes: int = 0


def framed(message: Message) -> bytes:
    """``message`` as the bytes that carry it."""
    parts = [np.ascontiguousarray(a) for a in message.arrays]
    text = message.text.encode()
    out = [HEAD.pack(message.kind, len(parts), message.cpu_s, message.max_rss_bytes, len(text)),
           text]  # fmt: skip
    for part in parts:
        out.append(ARRAY.pack(CODES[part.dtype], part.ndim))
        out.extend(DIM.pack(d) for d in part.shape)
    out.extend(part.tobytes() for part in parts)
    return b"".join(out)


def received(take: Callable[[int], bytes], *, max_bytes: int = MAX_ANSWER_BYTES) -> Message:
    """The next message of a stream whose bytes ``take(n)`` hands out; ``ValueError`` for
    bytes that carry no message, or arrays over ``max_bytes`` in all."""
    kind, count, cpu_s, rss, length = HEAD.unpack(take(HEAD.size))
    if length > MAX_TEXT_BYTES:
        raise ValueError(f"a text of {length} bytes")
    text = take(length).decode()
    shapes = []
    total = 0
    for _ in range(count):
        code, rank = ARRAY.unpack(take(ARRAY.size))
        if code not in DTYPES or rank > MAX_RANK:
            raise ValueError(f"an array of the code {code!r} and rank {rank}")
        shape = tuple(DIM.unpack(take(DIM.size))[0] for _ in range(rank))
        total += math.prod(shape) * DTYPES[code].itemsize
        if total > max_bytes:
            raise ValueError(f"arrays of over {max_bytes} bytes")
        shapes.append((DTYPES[code], shape))
    arrays = [
        np.frombuffer(take(math.prod(shape) * dtype.itemsize), dtype=dtype).reshape(shape)
        for dtype, shape in shapes
    ]
    return Message(kind, text, arrays, cpu_s, rss)


class _Reader:
    """Bytes read from a pipe, handed out in the sizes a message's parts have; ``fill``
    gives what is there (waiting for something), or raises ``EOFError``."""

    def __init__(self, fill: Callable[[], bytes]) -> None:
        self.fill = fill
        self.buffer = bytearray()

    def take(self, size: int) -> bytes:
        while len(self.buffer) < size:
            self.buffer += self.fill()
        taken = bytes(self.buffer[:size])
        del self.buffer[:size]
        return taken


def _signal_name(number: int) -> str:
    try:
        return signal.Signals(number).name
    except ValueError:
        return f"signal {number}"


class Sandbox:
    """A process that checks, loads and runs one network, within ``memory_bytes`` of address
    space and ``cpu_s`` CPU seconds in all (imports included)."""

    def __init__(self, *, memory_bytes: int, cpu_s: float) -> None:
        self.memory_bytes = memory_bytes
        self.cpu_s = cpu_s
        limits = (str(memory_bytes), str(math.ceil(cpu_s)), str(os.getpid()))
        # it starts in an empty folder of its own, knowing nothing of its parent's environment:
        # a path a model names resolves to nothing, and no secret is there to be read
        self.folder = tempfile.mkdtemp(prefix="nanonav-network-")
        work, home = os.path.join(self.folder, "work"), os.path.join(self.folder, "home")
        try:
            os.mkdir(work)
            os.mkdir(home)
            self._process = subprocess.Popen(
                [sys.executable, "-s", "-m", "nanonav.rl.sandbox", *limits],
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                stderr=subprocess.DEVNULL,
                cwd=work,
                env=bare_environment(home),
                start_new_session=True,
            )
        except BaseException:
            shutil.rmtree(self.folder, ignore_errors=True)
            raise
        assert self._process.stdin is not None and self._process.stdout is not None
        self._in = self._process.stdin.fileno()
        self._out = self._process.stdout.fileno()
        os.set_blocking(self._in, False)
        os.set_blocking(self._out, False)
        self._waiting: _Waiting | None = None
        self._reader = _Reader(self._fill)
        self.cpu_used_s = 0.0
        self.max_rss_bytes = 0

    @property
    def pid(self) -> int:
        return self._process.pid

    def __enter__(self) -> Sandbox:
        return self

    def __exit__(self, *_: object) -> None:
        self.close()

    def close(self) -> None:
        """Stop the process (killed: it holds nothing worth a goodbye)."""
        if self._process.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                self._process.kill()
        self._process.wait()
        for stream in (self._process.stdin, self._process.stdout):
            if stream is not None:
                with contextlib.suppress(OSError):
                    stream.close()
        shutil.rmtree(self.folder, ignore_errors=True)

    def labels(
        self, model: bytes, *, max_bytes: int, limit_s: float
    ) -> tuple[list[str] | None, list[str] | None]:
        """The observation and action labels ``model``'s metadata names
        (``nanonav.rl.graph.model_labels``), read in the process: the API parses no model."""
        asked = json.dumps({"max_bytes": max_bytes})
        message = Message(LABELS, asked, [np.frombuffer(model, dtype=np.uint8)])
        answer = self._ask(message, limit_s, None, "while its model's labels were read")
        if answer.kind != INFO:
            self._fail("it answered a question of labels with none")
        try:
            found = json.loads(answer.text)
            observation, actions = found["observation"], found["actions"]
        except (ValueError, KeyError, TypeError):
            self._fail("it answered a question of labels with none")
        for labels in (observation, actions):
            if labels is not None and not (
                isinstance(labels, list) and all(isinstance(x, str) for x in labels)
            ):
                self._fail("it answered a question of labels with none")
        return observation, actions

    def load(
        self, model: bytes, width: int, actions: int, *, continuous: bool, max_bytes: int,
        limit_s: float, keep_going: Callable[[], bool] | None = None,
    ) -> ModelInfo:  # fmt: skip
        """Check ``model`` (``nanonav.rl.graph.inspect_model``) and load it for ``run``, within
        ``limit_s`` seconds; its ``ModelInfo``, or ``InvalidModel`` saying why it cannot run;
        ``Interrupted`` as soon as ``keep_going`` answers False."""
        asked = json.dumps({"width": width, "actions": actions, "continuous": continuous,
                            "max_bytes": max_bytes})  # fmt: skip
        message = Message(LOAD, asked, [np.frombuffer(model, dtype=np.uint8)])
        answer = self._ask(message, limit_s, keep_going, "while its model was checked and loaded")
        if answer.kind != INFO:
            self._fail("it answered a load with no model's description")
        try:
            return ModelInfo.of_json(json.loads(answer.text))
        except (ValueError, KeyError, TypeError):
            self._fail("it answered a load with no model's description")

    def run(
        self,
        inputs: Sequence[NDArray[Any]],
        *,
        limit_s: float,
        keep_going: Callable[[], bool] | None = None,
    ) -> list[NDArray[Any]]:
        """The loaded model's outputs (its answer, then its memory) for its ``inputs`` (the
        observations, then the memory), within ``limit_s`` seconds; ``Interrupted`` as soon
        as ``keep_going`` answers False."""
        rows = inputs[0].shape[0] if inputs else 0
        doing = f"for one call of {rows} observations"
        answer = self._ask(Message(RUN, "", list(inputs)), limit_s, keep_going, doing)
        if answer.kind != ARRAYS:
            self._fail("it answered a run with no arrays")
        return answer.arrays

    def _ask(
        self,
        message: Message,
        limit_s: float,
        keep_going: Callable[[], bool] | None,
        doing: str,
    ) -> Message:
        self._waiting = _Waiting(time.monotonic() + limit_s, keep_going, limit_s, doing)
        try:
            self._write(memoryview(framed(message)))
            answer = received(self._reader.take)
        except (BrokenPipeError, EOFError):
            self._died(doing)
        except (ValueError, struct.error, UnicodeDecodeError) as error:
            self._fail(f"it answered what is not a message ({error})")
        finally:
            self._waiting = None
        self.cpu_used_s, self.max_rss_bytes = answer.cpu_s, answer.max_rss_bytes
        if answer.kind == REFUSED:
            raise InvalidModel(answer.text)
        if answer.kind == ERROR:
            raise SandboxFailed(f"the network failed {doing}: {answer.text}")
        return answer

    def _write(self, data: memoryview) -> None:
        while len(data):
            try:
                data = data[os.write(self._in, data) :]
            except BlockingIOError:
                self._wait(self._in, select.POLLOUT)

    def _fill(self) -> bytes:
        """What the process has written so far, waiting for something if nothing."""
        while True:
            try:
                chunk = os.read(self._out, READ_BYTES)
            except BlockingIOError:
                self._wait(self._out, select.POLLIN)
                continue
            if not chunk:
                raise EOFError
            return chunk

    def _wait(self, fd: int, event: int) -> None:
        """Wait until ``fd`` is ready, the exchange's deadline passes or its ``keep_going``
        says stop (both kill the process)."""
        waiting = self._waiting
        assert waiting is not None
        poll = select.poll()
        poll.register(fd, event | select.POLLHUP | select.POLLERR)
        while True:
            left = waiting.deadline - time.monotonic()
            if left <= 0:
                self.close()
                raise SandboxFailed(
                    f"the network took longer than {waiting.limit_s:g} s {waiting.doing}: its "
                    "process was stopped"
                )
            if poll.poll(1000 * min(left, POLL_S)):
                return
            if waiting.keep_going is not None and not waiting.keep_going():
                self.close()
                raise Interrupted("stopped while the network ran")

    def _died(self, doing: str) -> NoReturn:
        """Report how the process ended (it closed its pipes): by a signal, or by itself."""
        try:
            code = self._process.wait(timeout=5)
        except subprocess.TimeoutExpired:
            self.close()
            code = self._process.returncode
        self.close()
        if code < 0:
            name = _signal_name(-code)
            if -code in (signal.SIGXCPU, signal.SIGKILL):
                raise SandboxFailed(
                    f"the network's process was killed by {name} {doing}: it used more than "
                    f"its {self.cpu_s:g} s of CPU, or was stopped"
                )
            raise SandboxFailed(
                f"the network's process was killed by {name} {doing}: the model crashes ONNX "
                "Runtime"
            )
        raise SandboxFailed(f"the network's process ended (exit status {code}) {doing}")

    def _fail(self, what: str) -> NoReturn:
        self.close()
        raise SandboxFailed(f"the network's process misbehaved: {what}")


@dataclass(frozen=True)
class _Waiting:
    """One exchange: its deadline, what the caller's ``keep_going`` is, and how to say what
    was going on."""

    deadline: float
    keep_going: Callable[[], bool] | None
    limit_s: float
    doing: str


# ---------------------------------------------------------------- the process's own side


def _limit(memory_bytes: int, cpu_s: int, parent: int) -> None:
    """The process's limits, from now: its address space, ``cpu_s`` more seconds of CPU, no
    core dump, no file; and death with the thread of ``parent`` that started it."""
    import resource

    used = resource.getrusage(resource.RUSAGE_SELF)
    spent = math.ceil(used.ru_utime + used.ru_stime)
    resource.setrlimit(resource.RLIMIT_CPU, (spent + cpu_s, spent + cpu_s + CPU_GRACE_S))
    resource.setrlimit(resource.RLIMIT_AS, (memory_bytes, memory_bytes))
    resource.setrlimit(resource.RLIMIT_CORE, (0, 0))
    resource.setrlimit(resource.RLIMIT_FSIZE, (0, 0))
    die_with_parent(parent)


def _blocking_read() -> bytes:
    chunk = os.read(0, READ_BYTES)
    if not chunk:
        raise EOFError
    return chunk


def _send(fd: int, message: Message) -> None:
    import resource

    used = resource.getrusage(resource.RUSAGE_SELF)
    message.cpu_s = used.ru_utime + used.ru_stime
    message.max_rss_bytes = used.ru_maxrss * 1024
    data = memoryview(framed(message))
    while len(data):
        data = data[os.write(fd, data) :]


def _serve(memory_bytes: int, cpu_s: int, parent: int) -> None:
    """Answer the parent's messages until it closes the pipe."""
    import onnxruntime

    from nanonav.rl import graph

    # the protocol's own copy of the output; anything a library prints goes nowhere
    answers = os.dup(1)
    quiet = os.open(os.devnull, os.O_WRONLY)
    os.dup2(quiet, 1)
    _limit(memory_bytes, cpu_s, parent)
    session = None
    inputs: list[str] = []
    outputs: list[str] = []
    reader = _Reader(_blocking_read)
    while True:
        try:
            asked = received(reader.take, max_bytes=1 << 62)
        except EOFError:
            return
        try:
            if asked.kind == LABELS:
                given = json.loads(asked.text)
                sent = asked.arrays[0].tobytes()
                observation, actions = graph.model_labels(sent, max_bytes=given["max_bytes"])
                named = json.dumps({"observation": observation, "actions": actions})
                if len(named) > MAX_TEXT_BYTES // 2:
                    raise graph.InvalidModel(
                        f"the model's metadata names labels of {len(named):,} characters, over "
                        f"the {MAX_TEXT_BYTES // 2:,} an observation's and actions' may take"
                    )
                _send(answers, Message(INFO, named))
            elif asked.kind == LOAD:
                given = json.loads(asked.text)
                model = asked.arrays[0].tobytes()
                info = graph.inspect_model(
                    graph.parsed(model, given["max_bytes"]), given["width"], given["actions"],
                    continuous=given["continuous"],
                )  # fmt: skip
                session = _session(onnxruntime, model)
                inputs = [info.input_name, *(m.input_name for m in info.memory)]
                outputs = [info.output_name, *(m.output_name for m in info.memory)]
                _send(answers, Message(INFO, json.dumps(info.to_json())))
            elif session is not None:
                feeds = dict(zip(inputs, asked.arrays, strict=True))
                _send(answers, Message(ARRAYS, "", session.run(outputs, feeds)))
            else:
                _send(answers, Message(ERROR, "no model is loaded"))
        except graph.InvalidModel as refused:
            _send(answers, Message(REFUSED, str(refused)))
        except MemoryError:
            _send(answers, Message(ERROR, f"it needs more than the {memory_bytes:,} bytes of "
                                          "memory a network may take"))  # fmt: skip
        except Exception as error:
            text = str(error).strip().splitlines()
            detail = text[0] if text else type(error).__name__
            if "alloc" in detail.lower():
                detail += f" (a network may take {memory_bytes:,} bytes of memory)"
            _send(answers, Message(ERROR, detail[:1000]))


def _session(onnxruntime: Any, model: bytes) -> Any:
    """An ONNX Runtime session on one thread (a worker runs one job a core)."""
    options = onnxruntime.SessionOptions()
    options.intra_op_num_threads = 1
    options.inter_op_num_threads = 1
    options.log_severity_level = 3
    return onnxruntime.InferenceSession(model, options, providers=["CPUExecutionProvider"])


if __name__ == "__main__":
    _serve(int(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3]))
