"""Sensor 'counted': molecules counted, Poisson, by six receptor patches over an integration
time. A reading is 0 as often as counting expects where molecules are scarce, its mean and
spread are the counts', the gradient comes from the same counts, a count is held for its
window, and the integration time is checked and filled in."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from numba import njit
from numpy.typing import NDArray
from pydantic import ValidationError

from nanonav.engine import phases, sensing, simulate
from nanonav.engine.phases import Sim
from nanonav.engine.simulate import Run, kernel_params
from nanonav.engine.state import KernelParams, Swarm
from nanonav.scenario import PRESETS, Scenario, preset_scenario


@njit(cache=True)
def _counts(
    p: KernelParams, rng: np.random.Generator, s: Swarm, readings: NDArray[np.float64],
    gradients: NDArray[np.float64], average: bool,
) -> None:  # fmt: skip
    """Robot 0 counts ``len(readings)`` times where it is (each count a first, unless it
    ``average``s them as its gradient memory says)."""
    for j in range(readings.shape[0]):
        sensing.count_molecules(p, rng, s, 0, j == 0 or not average)
        readings[j] = s.sensed[0]
        for k in range(3):
            gradients[j, k] = s.sensed_grad[0, k]


@njit(cache=True)
def _poisson(rng: np.random.Generator, mean: float, out: NDArray[np.float64]) -> None:
    for j in range(out.shape[0]):
        out[j] = sensing.poisson_count(rng, mean)


@pytest.mark.parametrize("mean", [0.01, 0.7, 9.9, 10.0, 37.0, 5000.0])
def test_a_count_is_poisson_by_inversion_and_by_rejection(mean: float) -> None:
    # whole numbers, of Poisson's mean and variance; its chance of 0 below the switch
    n = 40_000
    out = np.zeros(n)
    _poisson(np.random.default_rng(5), mean, out)
    assert np.all(out == np.round(out)) and out.min() >= 0
    sd = math.sqrt(mean)
    assert abs(out.mean() - mean) < 4 * sd / math.sqrt(n)
    # the sample variance's sd is about sqrt(2 / n) sigma^2 (plus the fourth cumulant's share)
    assert out.var(ddof=1) == pytest.approx(mean, rel=4 * math.sqrt((2 + 1 / mean) / n))
    zero = math.exp(-mean)
    assert abs(np.mean(out == 0) - zero) < 4 * math.sqrt(zero * (1 - zero) / n) + 1e-9


def counted(**physics: Any) -> Scenario:
    return Scenario.model_validate({
        "physics": {"model": "active_brownian", "sensor": "counted", **physics},
        "robots": {"count": 1, "policy": "gradient"},
        "learning": {"episodes": 0, "max_steps": 200}, "evaluation": {"worlds": 1}, "seed": 3,
    })  # fmt: skip


def draws(
    scenario: Scenario, c: float, gradient: tuple[float, float, float], n: int,
    average: bool = False,
) -> tuple[KernelParams, NDArray[np.float64], NDArray[np.float64]]:  # fmt: skip
    run = Run(scenario, kernel_params(scenario))
    run.swarm.reading[0] = c
    run.swarm.reading_grad[0] = gradient
    readings, gradients = np.zeros(n), np.zeros((n, 3))
    _counts(run.params, np.random.default_rng(17), run.swarm, readings, gradients, average)
    return run.params, readings, gradients


def test_a_reading_of_a_hundredth_of_a_molecule_is_zero_as_often_as_poisson_counting() -> None:
    s = counted(robot_radius_um=1.0)
    per_nm = sensing.RECEPTOR_PATCHES * kernel_params(s).patch_counting  # molecules per nM
    expected = 0.01
    _, readings, gradients = draws(s, expected / per_nm, (0.0, 0.0, 0.0), 40_000)
    zeros = float(np.mean(readings == 0.0))
    poisson = math.exp(-expected)  # 0.990
    assert zeros >= poisson - 4 * math.sqrt(poisson * (1 - poisson) / len(readings))
    # a count of nothing points nowhere: the robot turns nothing
    assert np.all(gradients[readings == 0.0] == 0.0)
    # the counts themselves: a reading is a whole number of molecules over the body's counting
    assert np.allclose(readings * per_nm, np.round(readings * per_nm))


def test_readings_and_gradients_have_the_counts_mean_and_spread() -> None:
    s = counted(robot_radius_um=2.0)
    a = s.physics.robot_radius_um
    per_patch = kernel_params(s).patch_counting
    c = 400.0 / (sensing.RECEPTOR_PATCHES * per_patch)  # 400 molecules a count
    g = (0.02 * c / a, -0.01 * c / a, 0.0)  # a few per cent across the body
    n = 20_000
    _, readings, gradients = draws(s, c, g, n)
    # the reading: total / (6 P), Poisson of mean 400 -> relative sd 1 / sqrt(400)
    assert abs(readings.mean() - c) < 4 * c / math.sqrt(400 * n)
    assert readings.std() == pytest.approx(c / math.sqrt(400), rel=4 / math.sqrt(2 * n))
    # each component: (N+ - N-) / (2 a P), unbiased, with variance (mean N+ + mean N-) / (2aP)^2
    for k in range(3):
        ahead, behind = per_patch * (c + a * g[k]), per_patch * (c - a * g[k])
        sd = math.sqrt(ahead + behind) / (2 * a * per_patch)
        assert abs(gradients[:, k].mean() - g[k]) < 4 * sd / math.sqrt(n), k
        assert gradients[:, k].std() == pytest.approx(sd, rel=4 / math.sqrt(2 * n)), k


def test_the_gradient_memory_averages_the_counts_gradients_exponentially() -> None:
    # each count weighs w = integration time / memory = 0.1 / 0.5: the held gradient keeps the
    # counts' mean, and its variance falls to w / (2 - w) of one count's (an exponential
    # average's), while the reading is each count's own
    s = counted(robot_radius_um=2.0, gradient_memory_s=0.5)
    a = s.physics.robot_radius_um
    p = kernel_params(s)
    assert p.gradient_weight == pytest.approx(0.2)
    c = 400.0 / (sensing.RECEPTOR_PATCHES * p.patch_counting)
    g = (0.02 * c / a, 0.0, -0.01 * c / a)
    n = 40_000
    _, readings, gradients = draws(s, c, g, n, average=True)
    held = gradients[100:]  # past the first count's start
    sd_count = math.sqrt(2 * p.patch_counting * c) / (2 * a * p.patch_counting)
    w = p.gradient_weight
    for k in range(3):
        # successive held values are correlated (1 - w): the mean's sd is wider by sqrt((2-w)/w)
        sd_mean = sd_count * math.sqrt(w / (2 - w)) * math.sqrt((2 - w) / w / len(held))
        assert abs(held[:, k].mean() - g[k]) < 5 * sd_mean, k
        assert held[:, k].std() == pytest.approx(sd_count * math.sqrt(w / (2 - w)), rel=0.05), k
    assert readings.std() == pytest.approx(c / math.sqrt(400), rel=0.05)


def test_a_gradient_memory_belongs_to_counting() -> None:
    with pytest.raises(ValidationError) as raised:
        Scenario.model_validate({"physics": {"model": "active_brownian", "sensor": "each_step",
                                             "gradient_memory_s": 1}})  # fmt: skip
    assert raised.value.errors()[0]["loc"][-1] == "gradient_memory_s"
    assert kernel_params(counted(robot_radius_um=1.0)).gradient_weight == 1.0  # the last count


def test_a_count_is_held_for_its_integration_time() -> None:
    s = counted(robot_radius_um=1.0, dt_s=0.01, integration_time_s=0.05,
                secretion_molecules_s=1e6)  # fmt: skip
    assert kernel_params(s).window == 5
    t = simulate(s).trajectory
    assert t is not None and t.sensed is not None
    assert np.array_equal(t.step[:12], np.arange(12))  # a row every step
    sensed = t.sensed[1:, 0]
    changes = np.flatnonzero(np.diff(sensed) != 0)
    assert len(changes) >= 10  # it counted anew, window after window
    # the reading changes only where a window ends (two windows may count alike)
    assert np.all(np.diff(changes) % 5 == 0), changes


@pytest.mark.parametrize(
    ("physics", "field", "words"),
    [
        ({"sensor": "counted", "robot_radius_um": 5.0, "integration_time_s": 0.1},
         "integration_time_s", "r^2 / D_m = 0.25 s"),
        ({"sensor": "counted", "robot_radius_um": 0.5, "dt_s": 0.01, "integration_time_s": 0.005},
         "integration_time_s", "shorter than a step"),
        ({"sensor": "each_step", "integration_time_s": 0.5}, "integration_time_s",
         "belongs to sensor 'counted'"),
    ],
)  # fmt: skip
def test_an_integration_time_that_cannot_count_is_refused_naming_it(
    physics: dict[str, Any], field: str, words: str
) -> None:
    with pytest.raises(ValidationError) as raised:
        Scenario.model_validate({"physics": {"model": "active_brownian", **physics}})
    error = raised.value.errors()[0]
    assert error["loc"][-1] == field
    assert words in error["msg"]


def test_molecules_are_counted_unless_asked_otherwise() -> None:
    physics = Scenario.model_validate({"physics": {"model": "active_brownian"}}).physics
    assert physics.sensor == "counted" and physics.integration_time_s == 0.1
    for name in PRESETS:
        scenario = preset_scenario(name)
        if scenario.physics.model == "active_brownian":
            assert kernel_params(scenario).counted, name


def test_the_integration_time_is_filled_in_and_the_lattice_has_none() -> None:
    assert counted(robot_radius_um=1.0).physics.integration_time_s == 0.1
    assert counted(robot_radius_um=5.0).physics.integration_time_s == pytest.approx(0.25)
    assert Scenario.model_validate(
        {"physics": {"model": "active_brownian", "sensor": "each_step"}}
    ).physics.integration_time_s is None  # fmt: skip
    assert Scenario.model_validate({}).physics.integration_time_s is None
    with pytest.raises(ValidationError):
        Scenario.model_validate({"physics": {"sensor": "each_step"}})  # not the lattice's


def reached(policy: str, radius: float, dt: float, seed: int, worlds: int = 2) -> float:
    scenario = preset_scenario(
        "tumour-microswimmers", seed=seed,
        physics={"model": "active_brownian", "time_limit_s": 60.0, "robot_radius_um": radius,
                 "dt_s": dt, "sensor": "counted"},
        robots={"policy": policy}, learning={"episodes": 0}, evaluation={"worlds": worlds},
    )  # fmt: skip
    return float(simulate(scenario).summary["success_rate"])


def moved(policy: str, radius: float, worlds: int) -> float:
    """Success at dt/4 minus at dt, paired by seed (seeds no table used)."""
    return float(np.mean([reached(policy, radius, 0.0025, s, worlds)
                          - reached(policy, radius, 0.01, s, worlds)
                          for s in range(7000, 7004)]))  # fmt: skip


def test_counted_sensing_does_not_move_with_the_time_step() -> None:
    # benchmarks/convergence.py gives the whole table over 20 seeds: 'gradient' at 2 um moved
    # by +0.14 [+0.10, +0.18] when each step read anew, and by +0.00 [-0.01, +0.01] counted
    assert abs(moved("gradient", 2.0, 2)) < 0.03


def test_the_exact_bound_among_crowding_hard_spheres_barely_moves_with_the_time_step() -> None:
    # 5 um robots crowd the cell: a move into another robot or an obstacle refused whole (the
    # rule before hard-sphere contacts) cost the bound +0.14 [+0.12, +0.16] from dt to dt/4;
    # stopped at contact and sliding on, +0.04 [+0.03, +0.05] (benchmarks/convergence.py)
    assert moved("exact_gradient", 5.0, 4) < 0.09


def test_a_short_memory_must_be_shorter_than_the_long_one() -> None:
    with pytest.raises(ValidationError) as raised:
        counted(memory_s=1.0, short_memory_s=1.0)
    error = raised.value.errors()[0]
    assert error["loc"][-1] == "short_memory_s" and "shorter than memory_s" in error["msg"]
    assert kernel_params(counted(short_memory_s=0.25, dt_s=0.01)).recent_weight == 0.04


@njit(cache=True)
def _rises(p: KernelParams, rng: np.random.Generator, sim: Sim, truth: NDArray[np.float64],
           change: NDArray[np.float64]) -> None:  # fmt: skip
    """Robot 0 reads, again and again from nothing, a concentration that follows ``truth``
    step by step, its memory following each reading as a step's act does; ``change[k, t]`` is
    what it takes for a rise."""
    s = sim.s
    for k in range(change.shape[0]):
        s.prev_conc[0] = -1.0
        for t in range(truth.shape[0]):
            s.reading[0] = truth[t]
            phases.read_state(p, rng, sim, 0, t, 1e9, False)
            change[k, t] = sim.pc.obs[0, phases.OBS_CHANGE]
            reading = sim.pc.obs[0, phases.OBS_READING]
            s.prev_conc[0] += p.memory_weight * (reading - s.prev_conc[0])


def test_a_rise_is_told_from_the_recent_mean_more_surely_than_from_one_count() -> None:
    # about 13 molecules a count, as 'alonso-kirkegaard' 50 um from its source, rising 15 % a
    # second (5 um/s up a field whose relative gradient is 0.03 /um), or falling as much: one
    # count against the mean of 2 s tells which 88 % of the time, the mean of 0.5 s against it
    # 98-99 % (each count's relative error is 0.28; the means lag the reading)
    def told(short_s: float, way: float) -> float:
        scenario = counted(robot_radius_um=0.5, memory_s=2.0, short_memory_s=short_s,
                           dt_s=0.01)  # fmt: skip
        run = Run(scenario, kernel_params(scenario))
        per_nm = sensing.RECEPTOR_PATCHES * run.params.patch_counting
        t = np.arange(600) * 0.01
        truth = 13.0 / per_nm * np.exp(way * 0.15 * (t - 4.5))
        change = np.zeros((300, len(t)))
        _rises(run.params, np.random.default_rng(23), run.sim, truth, change)
        return float(np.mean(np.sign(change[:, 300:]) == way))  # once the memories filled

    for way in (1.0, -1.0):
        one, recent = told(0.0, way), told(0.5, way)
        assert one < 0.93, (way, one)
        assert recent > max(one + 0.05, 0.95), (way, one, recent)
