"""The bounds and defaults several parts of a scenario share: how full the cube may be, the
largest exact integer and episode, the signal's limits, the active Brownian learner's defaults."""

from __future__ import annotations

import math

# sensor 'counted': the integration time filled in, s (Alonso & Kirkegaard, PNAS Nexus 2024:
# their receptors count molecules over a step of 0.1 s), unless r^2 / D_m is longer
DEFAULT_INTEGRATION_TIME_S = 0.1


MAX_OBSTACLE_VOLUME_FRACTION = 0.3
DENSEST_PACKING = math.pi / math.sqrt(18)  # Kepler's bound: equal spheres fill at most 74 %
MAX_ROBOT_VOLUME_FRACTION = 0.1  # robots that take up space start apart at random: room to spare
# The signal's rates in each physics' units (communication): each physics refuses the other's.
LATTICE_SIGNAL = ("diffusion", "decay_rate", "release_rate")
BROWNIAN_SIGNAL = ("diffusion_um2_s", "decay_rate_s", "release_molecules_s")
# The largest seed or id: every integer up to it is exact in a JSON number whatever the client
# (a double, as I-JSON, RFC 7493, advises), so what a client sends is what is stored.
MAX_EXACT_INT = 2**53 - 1
MAX_STEPS = 1_000_000  # learning.max_steps: the longest episode
# learning.decisions of a network a job trains: the most, and the default (10^6: a few seconds
# of the trainer, ``docs/explanation/speed.md``)
MAX_TRAINING_DECISIONS = 10_000_000_000
TRAINING_DECISIONS = 1_000_000
# learning.checkpoint_decisions by default: about a minute of the trainer at its measured rate
CHECKPOINT_DECISIONS = 5_000_000
# The active Brownian learner's defaults, chosen on design seeds 5000-5007 at robot radii 0.5, 1,
# 2 and 5 µm (benchmarks/decision_interval.py; docs/explanation/learning.md, "Decisions in
# physical time"): a decision every second, and the visits schedule's exponent 0.6 (1 left the
# table unsettled there).
BROWNIAN_DECISION_INTERVAL_S = 1.0
BROWNIAN_ALPHA_EXPONENT = 0.6


# The signal's grid is updated at most every this many engine steps, so it keeps up with robots.
MAX_SIGNAL_EVERY = 10
LARGEST_DECAY_RATE = 50.0  # per step: a decay_rate of 1 (all of it) taken as this rate
