"""Fixed rules written as an outside policy: what a learner that steers continuously is
compared with, run by the same path (``nanonav.rl.evaluate``) as a network."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from nanonav.engine.observations import observation_of
from nanonav.engine.worlds import Worlds
from nanonav.scenario import Scenario


class TurnUpGradient:
    """The gradient rule as a continuous turn: toward the gradient a robot observes in its
    body frame, a steady turn that reaches that direction by the end of the decision interval
    (or turns as far as the interval allows). Deciding every step it is ``steer_up_gradient``
    (the same path, to rounding); held over an interval, it steers by the interval's mean
    reading."""

    def __init__(self, scenario: Scenario) -> None:
        labels = observation_of(scenario, "continuous").labels
        self.at = labels.index("gradient_forward")
        largest_per_step = Worlds(scenario, 1, "simultaneous", steering="continuous").params.turn
        self.largest = largest_per_step * scenario.decision_steps

    def __call__(self, rows: NDArray[np.float64]) -> NDArray[np.float64]:
        g = rows[:, self.at : self.at + 3]
        across = np.hypot(g[:, 1], g[:, 2])
        turns = np.zeros((rows.shape[0], 2))
        # no turn where the gradient's square underflows to 0, as steer_up_gradient turns none
        moves = (across > 0.0) & ((g * g).sum(axis=1) > 0.0)
        angle = np.arctan2(across[moves], g[moves, 0])
        share = np.minimum(1.0, angle / self.largest) / across[moves]
        turns[moves] = g[moves, 1:] * share[:, None]
        return turns
