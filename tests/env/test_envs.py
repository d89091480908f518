"""NanoNav through the RL ecosystem's interfaces: each env passes its ecosystem's own checker in
each physics, the vector env's worlds are single envs seeded alike, and an agent that acts as the
engine's greedy choice reproduces ``simulate``'s evaluation of the same table exactly."""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from numpy.typing import NDArray
from pettingzoo.test import parallel_api_test, parallel_seed_test
from pydantic import ValidationError

from nanonav.engine import simulate
from nanonav.env import ENV_ID, NanoNavEnv, NanoNavParallelEnv, NanoNavVectorEnv
from nanonav.scenario import Scenario

pytestmark = pytest.mark.timeout(300)

LATTICE = {"preset": "paper-single", "learning": {"max_steps": 80}}
BROWNIAN = {"preset": "tumour-microswimmers", "robots": {"count": 1},
            "physics": {"time_limit_s": 1.5}}  # fmt: skip
# a small space without obstacles, where a swimmer reaches its cell in some worlds (its cell
# secreting enough for a 1 um robot's counts to steer by)
# a cell near enough that a greedy table reaches it in some worlds and not others
BROWNIAN_NEAR = {**BROWNIAN, "space": {"size": 40}, "obstacles": {"count": 0},
                 "physics": {"time_limit_s": 10.0, "secretion_molecules_s": 1e4}}  # fmt: skip
LATTICE_SWARM = {"preset": "paper-swarm", "learning": {"max_steps": 60}}
BROWNIAN_SWARM = {"preset": "tumour-microswimmers", "robots": {"count": 8},
                  "physics": {"time_limit_s": 0.6}}  # fmt: skip
SIGNALLING = {"preset": "diffuse-tumour", "robots": {"count": 30, "policy": "q_learning"},
              "learning": {"max_steps": 60}}  # fmt: skip


def _with(base: dict[str, Any], **parts: dict[str, Any]) -> dict[str, Any]:
    return {**base, **parts}


@pytest.mark.parametrize(
    "scenario",
    [
        LATTICE,
        BROWNIAN,
        _with(
            SIGNALLING,
            robots={"count": 1, "policy": "q_learning"},
            communication={"model": "attractant_repellent"},
        ),
    ],
    ids=["lattice", "active_brownian", "lattice-attractant_repellent"],
)
def test_the_single_env_passes_gymnasiums_checker(scenario: dict[str, Any]) -> None:
    env = gymnasium.make(ENV_ID, scenario=scenario)
    check_env(env.unwrapped)
    obs, info = env.reset(seed=3)
    assert obs.shape == env.observation_space.shape and obs in env.observation_space
    assert isinstance(env.unwrapped, NanoNavEnv)
    assert 0 <= info["state"] < len(env.unwrapped.state_labels)


@pytest.mark.parametrize(
    "scenario",
    [
        LATTICE_SWARM,
        BROWNIAN_SWARM,
        _with(SIGNALLING, communication={"model": "attractant_repellent"}),
        _with(SIGNALLING, communication={"model": "broadcast"}),
        _with(BROWNIAN_SWARM, communication={"model": "attractant"}),
    ],
    ids=[
        "lattice",
        "active_brownian",
        "lattice-attractant_repellent",
        "lattice-broadcast",
        "active_brownian-attractant",
    ],
)
def test_the_swarm_env_passes_pettingzoos_api_and_seed_tests(scenario: dict[str, Any]) -> None:
    parallel_api_test(NanoNavParallelEnv(scenario), num_cycles=100)
    parallel_seed_test(lambda: NanoNavParallelEnv(scenario), num_cycles=100)


def _rollout(env: NanoNavEnv, seed: int, actions: NDArray[np.int64]) -> list[tuple[Any, ...]]:
    obs, _ = env.reset(seed=seed)
    out: list[tuple[Any, ...]] = [(obs,)]
    for action in actions:
        obs, reward, terminated, truncated, _ = env.step(action)
        out.append((obs, reward, terminated, truncated))
        if terminated or truncated:
            break
    return out


def test_the_vector_env_steps_each_world_as_a_single_env_seeded_alike() -> None:
    worlds = 3
    vector = gymnasium.make_vec(ENV_ID, num_envs=worlds, vectorization_mode="vector_entry_point",
                                scenario=LATTICE)  # fmt: skip
    assert isinstance(vector.unwrapped, NanoNavVectorEnv)
    assert isinstance(vector.single_action_space, gymnasium.spaces.Discrete)
    actions = np.random.default_rng(0).integers(0, vector.single_action_space.n, (200, worlds))
    singles = [_rollout(NanoNavEnv(LATTICE), 10 + k, actions[:, k]) for k in range(worlds)]
    obs, _ = vector.reset(seed=10)
    ended = np.zeros(worlds, dtype=bool)
    for k in range(worlds):
        np.testing.assert_array_equal(obs[k], singles[k][0][0])
    for t, row in enumerate(actions):
        obs, reward, terminated, truncated, _ = vector.step(row)
        for k in range(worlds):
            if ended[k] or t + 1 >= len(singles[k]):
                ended[k] = True
                continue
            want = singles[k][t + 1]
            np.testing.assert_array_equal(obs[k], want[0])
            assert (reward[k], terminated[k], truncated[k]) == want[1:]
        if ended.all():
            break
    assert ended.all(), "every world should have ended within 200 steps of 80"


def test_a_world_that_ended_is_drawn_afresh_at_the_next_step() -> None:
    vector = NanoNavVectorEnv(2, LATTICE)
    single = NanoNavEnv(LATTICE)
    vector.reset(seed=4)
    single.reset(seed=4)
    done = False
    while not done:
        _, _, terminated, truncated, _ = vector.step(np.zeros(2, dtype=np.int64))
        _, _, one_t, one_tr, _ = single.step(0)
        done = bool(terminated[0] or truncated[0])
        assert done == (one_t or one_tr)
    obs, reward, terminated, truncated, _ = vector.step(np.zeros(2, dtype=np.int64))
    np.testing.assert_array_equal(obs[0], single.reset()[0])
    assert reward[0] == 0.0 and not terminated[0] and not truncated[0]


def _greedy(scenario: Scenario, episodes: int) -> NDArray[np.float64]:
    """A table trained by ``simulate``, made greedy without ties (its first best action 1, the
    rest 0): the engine breaks ties at random, from a generator no agent outside shares."""
    trained = scenario.model_copy(update={"learning": scenario.learning.model_copy(
        update={"episodes": episodes})})  # fmt: skip
    table = simulate(trained).qtable
    assert table is not None
    values = np.asarray(table.values)
    greedy = np.zeros_like(values)
    np.put_along_axis(greedy, values.argmax(axis=-1)[..., None], 1.0, axis=-1)
    return greedy


def _evaluation(scenario: Scenario, table: NDArray[np.float64]) -> list[dict[str, Any]]:
    evaluated = scenario.model_copy(update={"learning": scenario.learning.model_copy(
        update={"episodes": 0})})  # fmt: skip
    return simulate(evaluated, policy=table).worlds


@pytest.mark.parametrize("base", [LATTICE, BROWNIAN_NEAR], ids=["lattice", "active_brownian"])
def test_the_env_driven_by_a_greedy_table_reproduces_simulates_evaluation(
    base: dict[str, Any],
) -> None:
    scenario = Scenario.model_validate(_with(base, evaluation={"worlds": 6}))
    table = _greedy(scenario, 20)
    env = NanoNavEnv(scenario)
    worlds = _evaluation(scenario, table)
    assert 0 < sum(world["reached"] for world in worlds) < len(worlds)
    for k, world in enumerate(worlds):
        _, info = env.reset(seed=scenario.seed) if k == 0 else env.reset()
        total, ended, terminated = 0.0, False, False
        while not ended:
            _, reward, terminated, truncated, info = env.step(int(table[info["state"]].argmax()))
            total += float(reward)
            ended = terminated or truncated
        assert info["step"] == world["episode_steps"], k
        assert int(terminated) == world["reached"], k
        assert total == pytest.approx(world["mean_return"], rel=1e-12, abs=1e-12), k


@pytest.mark.parametrize(
    "scenario", [LATTICE_SWARM, BROWNIAN_SWARM], ids=["lattice", "active_brownian"]
)
def test_the_swarms_dicts_and_arrays_are_the_same_steps(scenario: dict[str, Any]) -> None:
    by_dicts, by_arrays = NanoNavParallelEnv(scenario), NanoNavParallelEnv(scenario)
    obs, _ = by_dicts.reset(seed=5)
    all_obs, *_ = by_arrays.reset_arrays(seed=5)
    rng = np.random.default_rng(5)
    count = len(by_dicts.possible_agents)
    left = 0
    while by_dicts.agents:
        live = [by_dicts.possible_agents.index(a) for a in by_dicts.agents]
        assert live == [by_arrays.possible_agents.index(a) for a in by_arrays.agents]
        for agent, i in zip(by_dicts.agents, live, strict=True):
            np.testing.assert_array_equal(obs[agent], all_obs[i])
        chosen = rng.integers(0, len(by_dicts.action_labels), count)
        obs, rewards, terminated, truncated, _ = by_dicts.step(
            {a: int(chosen[i]) for a, i in zip(by_dicts.agents, live, strict=True)}
        )
        all_obs, all_rewards, all_terminated, all_truncated = by_arrays.step_arrays(chosen)
        assert set(rewards) == {by_dicts.possible_agents[i] for i in live}
        for agent, i in zip(rewards, live, strict=True):
            assert rewards[agent] == all_rewards[i]
            assert (terminated[agent], truncated[agent]) == (all_terminated[i], all_truncated[i])
            assert not (terminated[agent] and truncated[agent])
        done = np.flatnonzero(all_terminated | all_truncated)
        assert not (set(done.tolist()) - set(live)), "only live robots end"
        left += len(done)
    assert left == count, "every robot ended once, and the swarm with them"


def test_gymnasium_makes_it_by_module_too_with_its_own_spec() -> None:
    env = gymnasium.make("nanonav.env:NanoNav-v0", scenario=LATTICE)
    assert env.spec is not None and env.spec.id == ENV_ID
    assert isinstance(env.unwrapped, NanoNavEnv)
    first, _ = env.reset(seed=7)
    again, _ = NanoNavEnv(LATTICE).reset(seed=7)
    np.testing.assert_array_equal(first, again)


def test_what_a_user_can_get_wrong_is_refused_by_name() -> None:
    env = NanoNavEnv(LATTICE)
    with pytest.raises(RuntimeError, match="reset"):
        env.step(0)
    env.reset(seed=1)
    assert isinstance(env.action_space, gymnasium.spaces.Discrete)
    with pytest.raises(ValueError, match="action"):
        env.step(env.action_space.n)
    with pytest.raises(ValidationError, match="robots"):
        NanoNavEnv({"robots": {"speed": -1}})
    swarm = NanoNavParallelEnv(LATTICE_SWARM)
    swarm.reset(seed=1)
    with pytest.raises(ValueError, match="robot_3"):
        swarm.step({a: 0 for a in swarm.agents if a != "robot_3"})
    with pytest.raises(ValueError, match=r"robot_2's action 1\.5"):
        swarm.step({a: 1.5 if a == "robot_2" else 0 for a in swarm.agents})
    with pytest.raises(ValueError, match="robot_0's action -1"):
        swarm.step(dict.fromkeys(swarm.agents, -1))
    with pytest.raises(ValueError, match="shape"):
        swarm.step_arrays(np.zeros(3, dtype=np.int64))
    with pytest.raises(KeyError, match="robot_99"):
        swarm.observation_space("robot_99")
    vector = NanoNavVectorEnv(2, LATTICE)
    vector.reset(seed=0)
    with pytest.raises(ValueError, match="action -1"):
        vector.step(np.array([0, -1]))
    with pytest.raises(ValueError, match="float64, not integers"):
        vector.step(np.array([0.0, 1.5]))
