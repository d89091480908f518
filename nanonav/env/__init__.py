"""NanoNav as an environment: Gymnasium's ``NanoNavEnv`` (one robot) and ``NanoNavVectorEnv``
(many worlds in one compiled call); PettingZoo's ``NanoNavParallelEnv`` (the swarm, every robot
perceiving, then every robot acting) and ``NanoNavAECEnv`` (the swarm taking turns, as
``simulate`` steps it by default). Importing this package registers ``NanoNav-v0``, so
``gymnasium.make("NanoNav-v0", scenario={...})`` and ``gymnasium.make_vec("NanoNav-v0",
num_envs=N, vectorization_mode="vector_entry_point")`` work (or, without the import,
``gymnasium.make("nanonav.env:NanoNav-v0")``). Stable-Baselines3's ``NanoNavVecEnv`` lives in
``nanonav.env.baselines`` (the ``rl`` extra), imported only where it is used."""

from __future__ import annotations

from nanonav.engine.observations import OBSERVATION_LABELS
from nanonav.env.extra import EnvExtraMissing, register  # first of the envs: see its docstring
from nanonav.env.robot import NanoNavEnv, NanoNavVectorEnv
from nanonav.env.swarm import NanoNavParallelEnv
from nanonav.env.turns import NanoNavAECEnv

ENV_ID = "NanoNav-v0"

register(ENV_ID)

__all__ = [
    "ENV_ID",
    "OBSERVATION_LABELS",
    "EnvExtraMissing",
    "NanoNavAECEnv",
    "NanoNavEnv",
    "NanoNavParallelEnv",
    "NanoNavVectorEnv",
]
