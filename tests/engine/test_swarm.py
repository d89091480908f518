"""The swarm through ``simulate``: robots that take up space never overlap (lattice at 10,000
robots, active Brownian at 1,000) while robots that do not pile up; every swarm option is
bit-identical per seed; a capacity no swarm can fill changes nothing; a cell takes at most its
capacity, is treated by it, ends the episode when it is the last, and afterwards sheds only
``treated_secretion`` of its field; chemical signals and broadcasts start with the first
delivery, and a treated cell's repellent is read; Q-learning's table gains its signal dimension
and action; and validation names the field at fault."""

from __future__ import annotations

import copy
from typing import Any

import numpy as np
import pytest
from numpy.typing import NDArray
from pydantic import ValidationError
from scipy.spatial import cKDTree

from nanonav.engine import fields, metrics, qlearning
from nanonav.engine.contacts import grid_for, rebuild
from nanonav.engine.result import SimulationResult, Trajectory, without_timings
from nanonav.engine.simulation import simulate
from nanonav.engine.worlds import Worlds
from nanonav.scenario import Scenario, ScenarioError

COMMUNICATION_MODELS = ("none", "attractant", "attractant_repellent", "broadcast")


def merged(base: dict[str, Any], fields_: dict[str, Any]) -> dict[str, Any]:
    out = copy.deepcopy(base)
    for key, value in fields_.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = merged(out[key], value)
        else:
            out[key] = value
    return out


def swarm(**fields_: Any) -> Scenario:
    """The paper's swarm world (lattice, 50-unit cube, 10 obstacles), a fixed policy, one
    recorded evaluation world; ``fields_`` override it section by section."""
    base: dict[str, Any] = {
        "preset": "paper-swarm",
        "robots": {"policy": "rule"},
        "learning": {"episodes": 0, "max_steps": 200},
        "evaluation": {"worlds": 1},
    }
    return Scenario.model_validate(merged(base, fields_))


def swimmers(**fields_: Any) -> Scenario:
    """The tumour microswimmers' world (active Brownian, 150 um cube), shortened to 2 s."""
    base: dict[str, Any] = {
        "preset": "tumour-microswimmers",
        "physics": {"model": "active_brownian", "time_limit_s": 2.0},
        "robots": {"policy": "gradient"},
        "learning": {"episodes": 0},
        "evaluation": {"worlds": 1},
    }
    return Scenario.model_validate(merged(base, fields_))


def trajectory_of(result: SimulationResult) -> Trajectory:
    assert result.trajectory is not None
    return result.trajectory


def loads_of(t: Trajectory) -> NDArray[np.int64]:
    assert t.cell_loads is not None
    return t.cell_loads


def delivered_of(t: Trajectory) -> NDArray[np.int64]:
    assert t.delivered_to is not None
    return t.delivered_to


def signals_of(t: Trajectory) -> NDArray[np.float64]:
    assert t.signals is not None
    return t.signals


def overlapping_pairs(points: NDArray[np.float64], contact: float) -> int:
    """Pairs of robots whose centres are closer than ``contact`` (less a rounding margin)."""
    return len(cKDTree(points).query_pairs(contact - 1e-9))


def first_delivery_row(t: Trajectory) -> int:
    """The first history row whose cells had received any payload."""
    delivered = loads_of(t).sum(axis=1) > 0
    assert delivered.any(), "nobody delivered: the scenario tests nothing"
    return int(np.argmax(delivered))


# --- robots that take up space -------------------------------------------------------------


def test_ten_thousand_lattice_robots_that_take_up_space_never_overlap_and_do_bump() -> None:
    s = swarm(
        robots={"count": 10_000, "policy": "gradient", "exclusion": True},
        learning={"max_steps": 20},
    )
    result = simulate(s)
    t = trajectory_of(result)
    contact = 2 * s.robot_radius
    assert t.stride == 1 and t.robots.shape[0] == 21  # every step is checked
    for row in range(t.robots.shape[0]):
        assert overlapping_pairs(t.robots[row], contact) == 0, f"row {row}"
    assert result.worlds[0]["bumps"] > 0  # moves were refused: the check was needed
    assert result.summary["bumps"] == result.worlds[0]["bumps"]

    # the same swarm passing through itself piles up: gradient robots converge
    free = simulate(
        s.model_copy(update={"robots": s.robots.model_copy(update={"exclusion": False})})
    )
    pile = trajectory_of(free).robots
    first, last = overlapping_pairs(pile[0], contact), overlapping_pairs(pile[-1], contact)
    assert last > first > 0
    assert last > 1000  # a pile, not a few chance encounters


def test_active_brownian_robots_that_take_up_space_never_overlap() -> None:
    s = swimmers(robots={"count": 1_000, "exclusion": True})
    result = simulate(s)
    t = trajectory_of(result)
    contact = 2 * s.physics.robot_radius_um
    assert s.robot_radius == s.physics.robot_radius_um
    assert t.stride == 1 and t.robots.shape[0] == s.learning.max_steps + 1
    for row in range(t.robots.shape[0]):
        assert overlapping_pairs(t.robots[row], contact) == 0, f"row {row}"
    assert result.worlds[0]["bumps"] > 0
    # robots that pass through each other do overlap in this world
    free = simulate(swimmers(robots={"count": 1_000, "exclusion": False}))
    assert sum(overlapping_pairs(row, contact) for row in trajectory_of(free).robots) > 0


def test_robots_that_cannot_start_apart_are_refused_naming_the_robots() -> None:
    # 20,000 robots of radius 0.25 fill 1% of the cube, which validation accepts, but they must
    # start in the corner octant, (50/4)^3 units: 67% of it, beyond what random placement packs.
    # Whichever step refuses them, it should name what to change: the robots, not
    # reach_distance (which is not at fault: it is the default, and no robot is near a cell).
    data = merged(
        {"preset": "paper-swarm", "learning": {"episodes": 0, "max_steps": 5},
         "evaluation": {"worlds": 1}},
        {"robots": {"count": 20_000, "policy": "gradient", "exclusion": True, "start": "corner"}},
    )  # fmt: skip
    try:
        s = Scenario.model_validate(data)
    except ValidationError as error:
        assert error.errors()[0]["loc"][0] == "robots"
        return
    with pytest.raises(ScenarioError) as raised:
        simulate(s)
    assert raised.value.field.startswith("robots."), raised.value


# --- bit-identical -------------------------------------------------------------------------


def assert_same_run(a: SimulationResult, b: SimulationResult) -> None:
    assert without_timings(a.to_dict()) == without_timings(b.to_dict())
    assert [without_timings(w) for w in a.worlds] == [without_timings(w) for w in b.worlds]
    arrays_a, arrays_b = a.arrays(), b.arrays()
    assert arrays_a.keys() == arrays_b.keys()
    for name, array in arrays_a.items():
        assert np.array_equal(array, arrays_b[name]), name


@pytest.mark.parametrize("model", COMMUNICATION_MODELS)
def test_exclusion_capacity_and_signals_are_bit_identical_per_seed(model: str) -> None:
    s = swarm(
        seed=11,
        cells={"count": 3, "capacity": 3},
        robots={"count": 40, "policy": "q_learning", "exclusion": True, "radius": 0.4},
        learning={"episodes": 2, "max_steps": 150},
        evaluation={"worlds": 2},
        communication={"model": model},
    )
    a, b = simulate(s), simulate(s)
    assert_same_run(a, b)
    t = trajectory_of(a)
    assert (t.signals is None) == (model == "none")
    # the options were exercised: robots bumped, and cells were treated in both worlds
    assert all(w["bumps"] > 0 and w["cells_treated"] > 0 for w in a.worlds)
    other = simulate(s.model_copy(update={"seed": 12}))
    assert not np.array_equal(t.robots, trajectory_of(other).robots)


@pytest.mark.parametrize("model", COMMUNICATION_MODELS)
def test_active_brownian_swarm_options_are_bit_identical_per_seed(model: str) -> None:
    # a 60 um cube where robots reach the cells within 3 s, and the first is treated (cells
    # secreting enough for a 1 um robot's counts to steer by)
    s = swimmers(
        seed=5,
        space={"size": 60.0},
        obstacles={"count": 10},
        physics={"time_limit_s": 3.0, "secretion_molecules_s": 1e5},
        cells={"count": 2, "capacity": 3},
        robots={"count": 100, "exclusion": True},
        evaluation={"worlds": 2},
        communication={"model": model},
    )
    a = simulate(s)
    assert_same_run(a, simulate(s))
    assert a.worlds[0]["cells_treated"] >= 1 and a.worlds[0]["bumps"] > 0


# --- capacity ------------------------------------------------------------------------------


def without_swarm(world: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in world.items() if k != "duration_s" and k not in metrics.SWARM}


def test_a_capacity_no_swarm_can_fill_changes_nothing() -> None:
    # 15 robots can deliver at most 15 payloads: a capacity of 100,000 treats no cell
    unlimited = swarm(
        seed=3,
        robots={"policy": "q_learning"},
        learning={"episodes": 3, "max_steps": 150},
        evaluation={"worlds": 2},
    )
    limited = unlimited.model_copy(
        update={"cells": unlimited.cells.model_copy(update={"capacity": 10**5})}
    )
    a, b = simulate(unlimited), simulate(limited)
    assert [without_swarm(w) for w in a.worlds] == [without_swarm(w) for w in b.worlds]
    assert without_swarm(a.summary) == without_swarm(b.summary)
    assert a.episodes == b.episodes
    assert np.array_equal(trajectory_of(a).robots, trajectory_of(b).robots)
    assert a.qtable is not None and b.qtable is not None
    assert np.array_equal(a.qtable.values, b.qtable.values)
    # the swarm's numbers appear only with the option, and say no cell was treated
    assert not set(metrics.SWARM) & a.worlds[0].keys()
    assert b.worlds[0]["cells_treated"] == 0 and b.worlds[0]["time_to_treat_all"] == 150
    assert a.worlds[0]["reached"] > 0  # robots did deliver


CAPACITY_WORLD: dict[str, Any] = {
    "cells": {"count": 3, "capacity": 2},
    "robots": {"count": 60, "policy": "rule"},
    "learning": {"max_steps": 400},
}


@pytest.mark.parametrize("seed", [0, 1])
def test_a_cell_takes_at_most_its_capacity_and_the_last_treatment_ends_the_episode(
    seed: int,
) -> None:
    s = swarm(seed=seed, **CAPACITY_WORLD)
    capacity = 2
    result = simulate(s)
    world = result.worlds[0]
    t = trajectory_of(result)
    loads, delivered = loads_of(t), delivered_of(t)
    assert loads.max() <= capacity
    assert np.all(np.diff(loads, axis=0) >= 0)  # a payload stays delivered
    counted = np.bincount(delivered[delivered >= 0], minlength=s.cells.count)
    assert counted.max() <= capacity
    assert np.array_equal(counted, loads[-1])
    assert world["most_robots_on_a_cell"] == loads[-1].max()
    assert world["robots_per_cell"] == pytest.approx(loads[-1].mean())
    assert world["cells_treated"] == int((loads[-1] == capacity).sum())
    assert world["treated_fraction"] == pytest.approx(world["cells_treated"] / s.cells.count)
    # robots that delivered nothing were turned away and are still searching
    idle = delivered == -1
    assert idle.any()
    assert not t.reached[idle].any()
    assert world["never_delivered"] == pytest.approx(idle.mean())
    assert np.array_equal(t.reached, delivered >= 0)
    # every cell was treated in this world: the episode ended with the last treatment
    assert world["cells_treated"] == s.cells.count
    treated_row = int(np.argmax((loads == capacity).all(axis=1)))
    assert world["time_to_treat_all"] == int(t.step[treated_row])
    assert world["episode_steps"] == world["time_to_treat_all"], (
        f"every cell was treated at step {world['time_to_treat_all']} but the episode ran to "
        f"step {world['episode_steps']} (max_steps {s.learning.max_steps})"
    )
    assert t.length == world["time_to_treat_all"]
    assert np.all(t.robot_steps[idle] == world["episode_steps"])  # searched to the end


def test_robots_come_within_reach_of_a_treated_cell_and_keep_searching() -> None:
    s = swarm(seed=0, **CAPACITY_WORLD)
    t = trajectory_of(simulate(s))
    loads, delivered = loads_of(t), delivered_of(t)
    turned_away = 0
    for row in range(1, t.robots.shape[0]):
        treated = np.flatnonzero(loads[row - 1] >= 2)  # treated before this row's step
        searching = delivered == -1
        if not 0 < len(treated) < s.cells.count:  # robots search while a cell is left
            continue
        gaps = np.linalg.norm(
            t.robots[row][searching][:, None, :] - t.cells[row][treated][None, :, :], axis=2
        )
        turned_away += int((gaps <= s.reach_distance).any(axis=1).sum())
    assert turned_away > 0  # robots were where they would have delivered to an untreated cell


@pytest.mark.parametrize("seed", [0, 1])
def test_without_a_capacity_the_same_world_piles_robots_on_a_cell(seed: int) -> None:
    world = merged(CAPACITY_WORLD, {"cells": {"capacity": None}})
    t = trajectory_of(simulate(swarm(seed=seed, **world)))
    assert loads_of(t)[-1].max() > 2


@pytest.mark.parametrize("share", [0.0, 0.3])
def test_a_treated_cell_sheds_only_its_treated_secretion(share: float) -> None:
    # two cells that one payload treats: the true concentration each row records is the
    # field of the untreated cells plus `share` of the treated ones', a cell counting as
    # treated from the step after its treatment (its sources are placed at a step's start)
    s = swarm(seed=0, cells={"count": 2, "capacity": 1, "treated_secretion": share},
              robots={"count": 30})  # fmt: skip
    t = trajectory_of(simulate(s))
    loads = loads_of(t)
    checked = 0
    for row in range(1, t.robots.shape[0]):
        treated = loads[row - 1] >= 1
        if not treated.any():
            continue
        alone = [
            fields.field_and_gradient(
                s.biomarker, t.cells[row][[j]], t.emitter_offsets[[j]], t.robots[row]
            )[0]
            for j in range(s.cells.count)
        ]
        expected = sum((share if treated[j] else 1.0) * alone[j] for j in range(s.cells.count))
        # the engine takes the lost share off the full sum: equal up to rounding
        np.testing.assert_allclose(t.concentration[row], expected, rtol=1e-12, atol=1e-14)
        checked += 1
    assert checked >= 3  # rows recorded after a treatment, before the other cell is treated
    # and before any treatment the field is every cell's, in full
    before = int(np.argmax(loads.sum(axis=1) > 0))
    full = fields.field_and_gradient(s.biomarker, t.cells[before], t.emitter_offsets,
                                     t.robots[before])[0]  # fmt: skip
    np.testing.assert_allclose(t.concentration[before], full, rtol=1e-12, atol=1e-14)


# --- communication -------------------------------------------------------------------------


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_attractant_is_read_only_after_the_first_delivery(seed: int) -> None:
    s = swarm(seed=seed, robots={"count": 60}, communication={"model": "attractant"})
    t = trajectory_of(simulate(s))
    sig = signals_of(t)
    assert sig.shape == t.concentration.shape
    first = first_delivery_row(t)
    # released by bound robots from the next update on: nothing to read until then
    assert np.all(sig[: first + 1] == 0.0)
    assert sig[first + 1 :].max() > s.communication.threshold
    assert sig.min() >= 0.0  # an attractant alone never reads negative


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_treated_cells_repellent_is_read_after_its_treatment(seed: int) -> None:
    s = swarm(seed=seed, cells={"count": 3, "capacity": 3}, robots={"count": 60},
              communication={"model": "attractant_repellent"})  # fmt: skip
    t = trajectory_of(simulate(s))
    sig, loads = signals_of(t), loads_of(t)
    treated = (loads >= 3).any(axis=1)
    assert treated.any()
    first_treated = int(np.argmax(treated))
    # before any cell is treated only attractant is released: the net signal is not negative
    assert sig[: first_treated + 1].min() >= 0.0
    assert sig[: first_treated + 1].max() > s.communication.threshold
    # a treated cell's bound robots release repellent, which robots then read
    assert sig[first_treated + 1 :].min() < -s.communication.threshold


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_a_broadcast_reaches_robots_within_range_after_a_delivery(seed: int) -> None:
    s = swarm(seed=seed, robots={"count": 60}, communication={"model": "broadcast"})
    t = trajectory_of(simulate(s))
    sig = signals_of(t)
    assert set(np.unique(sig)) <= {0.0, 1.0}
    first = first_delivery_row(t)
    # a robot moving after the sender in the same step may read the message in that step
    assert np.all(sig[:first] == 0.0)
    heard_rows = np.flatnonzero((sig > 0).any(axis=1))
    assert len(heard_rows) and heard_rows[0] >= first
    row = int(heard_rows[0])
    delivered = delivered_of(t)
    senders = np.flatnonzero((delivered >= 0) & (t.robot_steps <= t.step[row]))
    hearers = np.flatnonzero(sig[row] > 0)
    assert len(senders) and len(hearers)
    # a sender's position is where it stays bound; a hearer was sent it from where it was
    # before or after its own move of that step
    for h in hearers:
        gap = min(
            float(np.linalg.norm(t.robots[r][h] - t.robots[row][q]))
            for q in senders
            for r in (row - 1, row)
        )
        assert gap < s.communication.range, (h, gap)


# --- Q-learning's table --------------------------------------------------------------------


def q_run(model: str, *, brownian: bool = False, max_steps: int = 10) -> SimulationResult:
    common: dict[str, Any] = {
        "robots": {"count": 15, "policy": "q_learning"},
        "learning": {"episodes": 1},
        "communication": {"model": model},
    }
    if brownian:
        return simulate(swimmers(**merged(common, {"physics": {"time_limit_s": 0.1}})))
    return simulate(swarm(**merged(common, {"learning": {"max_steps": max_steps}})))


@pytest.mark.parametrize(
    ("model", "signals"),
    [("none", []), ("attractant", qlearning.CHEMICAL_SIGNALS),
     ("attractant_repellent", qlearning.CHEMICAL_SIGNALS), ("broadcast", ["none", "message"])],
)  # fmt: skip
def test_the_q_table_gains_a_signal_dimension_and_action(model: str, signals: list[str]) -> None:
    qt = q_run(model).qtable
    assert qt is not None
    base = qlearning.behavior_states()
    assert len(base) == 72
    if not signals:
        assert qt.states == base and qt.actions == qlearning.BEHAVIOR_ACTIONS
        assert "follow_signal" not in qt.actions
    else:
        assert len(qt.states) == 72 * len(signals)
        # the signal is the last, least significant dimension
        for index, label in enumerate(qt.states):
            assert label == f"{base[index // len(signals)]}|signal={signals[index % len(signals)]}"
        assert qt.actions == [*qlearning.BEHAVIOR_ACTIONS, "follow_signal"]
    assert qt.values.shape == (len(qt.states), len(qt.actions))
    assert (qt.states, qt.actions) == qlearning.labels("behaviors", model)


def test_active_brownian_steering_gains_steer_to_signal() -> None:
    qt = q_run("attractant", brownian=True).qtable
    assert qt is not None
    assert len(qt.states) == 32 * 4 and all("|signal=" in label for label in qt.states)
    assert qt.actions == [*qlearning.STEERING_ACTIONS, "steer_to_signal"]
    assert qt.values.shape == (32 * 4, 5)


@pytest.mark.parametrize("model", ["attractant", "broadcast"])
def test_before_any_delivery_every_visited_state_has_no_signal(model: str) -> None:
    # three steps of one training episode in which no robot reached a cell (checked): nothing
    # was ever released or sent, so every state the kernel visited must be labelled 'none'
    result = q_run(model, max_steps=3)
    assert result.episodes[0]["success_rate"] == 0.0
    qt = result.qtable
    assert qt is not None
    visits = qt.visits.sum(axis=1)
    assert visits.sum() > 0
    silent = np.array([label.endswith("|signal=none") for label in qt.states])
    assert visits[~silent].sum() == 0


# --- validation ----------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("data", "loc"),
    [
        ({"communication": {"diffusion_um2_s": 50.0}}, ("communication", "diffusion_um2_s")),
        ({"communication": {"release_molecules_s": 10.0}},
         ("communication", "release_molecules_s")),
        ({"preset": "tumour-microswimmers", "communication": {"diffusion": 1.0}},
         ("communication", "diffusion")),
        ({"preset": "tumour-microswimmers", "communication": {"decay_rate": 0.5}},
         ("communication", "decay_rate")),
        ({"robots": {"policy": "q_learning"}, "learning": {"actions": "directions"},
          "communication": {"model": "broadcast"}}, ("learning", "actions")),
        ({"robots": {"policy": "q_learning"}, "learning": {"actions": "directions"},
          "communication": {"model": "attractant"}}, ("learning", "actions")),
        ({"preset": "tumour-microswimmers", "robots": {"radius": 0.5}}, ("robots", "radius")),
        ({"robots": {"count": 100_000, "exclusion": True, "radius": 2.0}}, ("robots", "count")),
        # 10% of the cube: 2,984 robots of radius 1 fit, 2,985 do not
        ({"robots": {"count": 2_985, "exclusion": True, "radius": 1.0}}, ("robots", "count")),
        ({"robots": {"count": 100_001}}, ("robots", "count")),
        ({"cells": {"capacity": 0}}, ("cells", "capacity")),
        ({"cells": {"treated_secretion": 1.5}}, ("cells", "treated_secretion")),
        ({"communication": {"model": "smoke"}}, ("communication", "model")),
    ],
)  # fmt: skip
def test_each_swarm_field_out_of_bounds_is_refused_by_name(
    data: dict[str, Any], loc: tuple[str, ...]
) -> None:
    with pytest.raises(ValidationError) as raised:
        Scenario.model_validate(data)
    assert [error["loc"] for error in raised.value.errors()] == [loc]


@pytest.mark.parametrize(
    "data",
    [
        {"robots": {"count": 2_984, "exclusion": True, "radius": 1.0}},
        {"robots": {"count": 100_000}},  # without exclusion robots take no room
        {"robots": {"count": 100_000, "exclusion": True}},  # of radius 0.25: 5% of the cube
        {"robots": {"policy": "q_learning"}, "learning": {"actions": "directions"}},
        {"robots": {"policy": "rule"}, "learning": {"actions": "directions"},
         "communication": {"model": "broadcast"}},  # a fixed policy has no action set to use
        {"preset": "tumour-microswimmers", "communication": {"diffusion_um2_s": 50.0}},
        {"cells": {"capacity": 1, "treated_secretion": 1.0}},
    ],
)  # fmt: skip
def test_the_swarm_fields_within_bounds_are_accepted(data: dict[str, Any]) -> None:
    accepted = Scenario.model_validate(data).model_dump(mode="json")
    for section, given in data.items():  # each value given is the one kept, none adjusted
        if section == "preset":
            assert accepted["preset"] == given
            continue
        for name, value in given.items():
            assert accepted[section][name] == value, (section, name)


def test_a_swimmer_that_slides_on_a_contact_is_listed_where_it_ends_for_the_radio() -> None:
    # robots crowded among obstacles slide at contacts; the broadcast's cell list (no slack)
    # must list each robot in the bucket it is in after every step, or a search misses it
    s = swimmers(
        seed=3,
        space={"size": 40.0},
        obstacles={"count": 30},
        physics={"time_limit_s": 30.0},
        robots={"count": 40, "exclusion": True},
        learning={"decision_interval_s": 0.01},  # a step an env step: each one is checked
        communication={"model": "broadcast", "range": 2.0},
    )
    worlds = Worlds(s, 1, "simultaneous")
    worlds.seed([3])
    worlds.step(None, np.ones(1, dtype=np.bool_))
    b = worlds.batch
    fresh = grid_for(s.space.size / 2, s.communication.range, 0.0, s.robots.count)
    assert fresh.dims > 2 and fresh.dims == b.radio.dims  # a robot can change cells
    slid = 0
    for _ in range(2000):
        before = b.s.pos[0].copy()
        worlds.step(np.zeros((1, s.robots.count), dtype=np.int64), np.zeros(1, dtype=np.bool_))
        slid += int(np.sum(np.any(b.s.pos[0] != before, axis=1) & b.s.blocked[0]))
        rebuild(fresh, b.s.pos[0], b.s.active[0])
        active = b.s.active[0]
        np.testing.assert_array_equal(b.radio.cell[0][active], fresh.cell[active])
    assert slid > 0  # contacts that moved the robot were exercised
