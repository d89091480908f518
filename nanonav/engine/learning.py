"""The Q update (eq. 2.7): a transition is learned bootstrapped from the robot's next state once
that is known, or from its reward alone when it ended the robot's episode.

A room of its own because learning is apart from what is sensed and how things move; the
vocabulary (states, actions, labels, the epsilon schedule) is in ``qlearning``, and the swarm's
pending slots, where a transition waits for its next state, are filled in the kernel's loop.
Everything here runs under numba, inlined into the compiled step.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from nanonav.engine.compiled import inlined
from nanonav.engine.state import ALPHA_VISITS, KernelParams


@inlined
def q_update(
    p: KernelParams,
    q: NDArray[np.float64],
    visits: NDArray[np.int64],
    table: int,
    s: int,
    a: int,
    target: float,
) -> None:
    """Move Q(s, a) of ``table`` toward ``target`` by the step size of the visits so far."""
    # eq. 2.7: Q(s,a) <- Q(s,a) + alpha [r + gamma max_a' Q(s',a') - Q(s,a)], alpha constant or
    # alpha / N(s,a)^omega over the visits N of (s, a)
    alpha = p.alpha
    if p.alpha_schedule == ALPHA_VISITS and visits[table, s, a] > 1:
        n = visits[table, s, a]
        alpha = p.alpha / n if p.alpha_exponent == 1.0 else p.alpha / n**p.alpha_exponent
    q[table, s, a] += alpha * (target - q[table, s, a])


@inlined
def _bootstrap(p: KernelParams, q: NDArray[np.float64], table: int, s: int, reward: float) -> float:
    best: float = q[table, s, 0]
    for a in range(1, q.shape[2]):
        best = max(best, q[table, s, a])
    return reward + p.gamma * best


@inlined
def q_update_bootstrapped(
    p: KernelParams,
    q: NDArray[np.float64],
    visits: NDArray[np.int64],
    table: int,
    s: int,
    a: int,
    reward: float,
    next_state: int,
) -> None:
    """Learn the transition (s, a, reward) now that its next state is known: the target
    r + gamma max_a' Q(s', a') of eq. 2.7."""
    target = _bootstrap(p, q, table, next_state, reward)
    q_update(p, q, visits, table, s, a, target)
