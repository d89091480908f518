"""How a run of a policy from outside ends early, as plain exceptions: the sandboxed network
and the evaluation both raise them, and the worker and the API catch them, without loading the
engine."""

from __future__ import annotations


class PolicyFailed(RuntimeError):
    """The outside policy answered what no robot can do (or raised); the message says what."""


class Stopped(Exception):
    """Raised by a ``decide`` that was told, while it decided, that the run should stop (a
    network asks the worker whether its job goes on): the run ends as when ``progress``
    answers False."""
