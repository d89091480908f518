"""Sensor 'counted': molecules counted, Poisson, by six receptor patches of an absorbing body
over an integration time. A still body takes in Berg and Purcell's 4 pi D a c N s / (N s + pi a)
a second, and its front and back patches the absorber's gradient term 3 g cos(theta) over their
surfaces; a count is of the window just past, along the path, known at its end. A reading is 0
as often as counting expects where molecules are scarce, its mean and spread are the counts',
the gradient comes from the same counts, a count is held for its window, and the integration
time is checked and filled in."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from numba import njit
from numpy.typing import NDArray
from pydantic import ValidationError
from scipy.integrate import quad

from nanonav.engine import observations, phases, sensing, simulate
from nanonav.engine.phases import Sim
from nanonav.engine.simulation import Run, kernel_params
from nanonav.engine.state import KernelParams, Swarm
from nanonav.scenario import PRESETS, Scenario, preset_scenario


@njit(cache=True)
def _counts(
    p: KernelParams, rng: np.random.Generator, s: Swarm, readings: NDArray[np.float64],
    gradients: NDArray[np.float64], average: bool,
) -> None:  # fmt: skip
    """Robot 0 counts ``len(readings)`` windows where it is (each count a first, unless it
    ``average``s them as its gradient memory says)."""
    for j in range(readings.shape[0]):
        sensing.take_in(p, s, 0, float(p.window))
        sensing.count_molecules(p, rng, s, 0, j == 0 or not average)
        readings[j] = s.sensed[0]
        for k in range(3):
            gradients[j, k] = s.sensed_grad[0, k]


@njit(cache=True)
def _patch_counts(
    p: KernelParams, rng: np.random.Generator, s: Swarm, field: NDArray[np.float64],
    out: NDArray[np.float64],
) -> None:  # fmt: skip
    """Robot 0's six patch counts of ``len(out)`` windows, the concentration at it in each
    step of a window ``field[step]`` (its gradient held): the counts drawn as the engine
    draws them, from what each patch took in."""
    for j in range(out.shape[0]):
        for step in range(p.window):
            s.reading[0] = field[step]
            sensing.take_in(p, s, 0, 1.0)
        for k in range(sensing.RECEPTOR_PATCHES):
            out[j, k] = sensing.poisson_count(rng, s.window_flux[0, k])
        s.window_flux[0, :] = 0.0


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


def per_window(p: KernelParams) -> tuple[float, float]:
    """What a patch takes in over a window: per nM, and per nM/um of gradient toward it."""
    return p.window * p.patch_rate, p.window * p.patch_gradient_rate


def test_a_reading_of_a_hundredth_of_a_molecule_is_zero_as_often_as_poisson_counting() -> None:
    s = counted(robot_radius_um=1.0)
    per_nm = sensing.RECEPTOR_PATCHES * per_window(kernel_params(s))[0]  # molecules per nM
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
    per_patch, per_gradient = per_window(kernel_params(s))
    c = 400.0 / (sensing.RECEPTOR_PATCHES * per_patch)  # 400 molecules a count
    g = (0.02 * c / a, -0.01 * c / a, 0.0)  # a few per cent across the body
    n = 20_000
    _, readings, gradients = draws(s, c, g, n)
    # the reading: total / (6 P), Poisson of mean 400 -> relative sd 1 / sqrt(400)
    assert abs(readings.mean() - c) < 4 * c / math.sqrt(400 * n)
    assert readings.std() == pytest.approx(c / math.sqrt(400), rel=4 / math.sqrt(2 * n))
    # each component: (N+ - N-) / (2 G), unbiased, with variance (mean N+ + mean N-) / (2 G)^2
    for k in range(3):
        ahead, behind = per_patch * c + per_gradient * g[k], per_patch * c - per_gradient * g[k]
        sd = math.sqrt(ahead + behind) / (2 * per_gradient)
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
    per_patch, per_gradient = per_window(p)
    c = 400.0 / (sensing.RECEPTOR_PATCHES * per_patch)
    g = (0.02 * c / a, 0.0, -0.01 * c / a)
    n = 40_000
    _, readings, gradients = draws(s, c, g, n, average=True)
    held = gradients[100:]  # past the first count's start
    sd_count = math.sqrt(2 * per_patch * c) / (2 * per_gradient)
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


def moved(policy: str, radius: float, worlds: int, seeds: int = 4) -> NDArray[np.float64]:
    """Success at dt/4 minus at dt, paired by seed, a difference a seed (seeds no table
    used)."""
    return np.array([reached(policy, radius, 0.0025, s, worlds)
                     - reached(policy, radius, 0.01, s, worlds)
                     for s in range(7000, 7000 + seeds)])  # fmt: skip


def test_counted_sensing_does_not_move_with_the_time_step() -> None:
    # benchmarks/convergence.py gives the whole table over 20 seeds: 'gradient' at 2 um moved
    # by +0.14 [+0.10, +0.18] when each step read anew, and by +0.01 [-0.02, +0.03] counted
    differences = moved("gradient", 2.0, 4, seeds=12)
    error = differences.std(ddof=1) / math.sqrt(len(differences))
    assert error < 0.03  # enough worlds to see a move of 0.1
    assert abs(differences.mean()) < 3 * error


def test_the_exact_bound_among_crowding_hard_spheres_barely_moves_with_the_time_step() -> None:
    # 5 um robots crowd the cell: a move into another robot or an obstacle refused whole (the
    # rule before hard-sphere contacts) cost the bound +0.14 [+0.12, +0.16] from dt to dt/4;
    # stopped at contact and sliding on, +0.04 [+0.03, +0.05] (benchmarks/convergence.py)
    assert moved("exact_gradient", 5.0, 4).mean() < 0.09


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
        s.window_flux[0, :] = 0.0
        for t in range(truth.shape[0]):
            s.reading[0] = truth[t]
            phases.read_state(p, rng, sim, 0, t, 1e9, False)
            change[k, t] = sim.pc.obs[0, observations.OBS_CHANGE]
            reading = sim.pc.obs[0, observations.OBS_READING]
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
        per_nm = sensing.RECEPTOR_PATCHES * run.params.window * run.params.patch_rate
        t = np.arange(600) * 0.01
        truth = 13.0 / per_nm * np.exp(way * 0.15 * (t - 4.5))
        change = np.zeros((300, len(t)))
        _rises(run.params, np.random.default_rng(23), run.sim, truth, change)
        return float(np.mean(np.sign(change[:, 300:]) == way))  # once the memories filled

    for way in (1.0, -1.0):
        one, recent = told(0.0, way), told(0.5, way)
        assert one < 0.93, (way, one)
        assert recent > max(one + 0.05, 0.95), (way, one, recent)


MOLECULES_PER_UM3_PER_NM = 0.6022140857


def shadow_of_a_patch() -> float:
    """The integral of cos(theta) over the patch facing +x of the unit sphere (its points
    nearer +x than any other axis's way): the area of its shadow on the y-z plane, where
    x = sqrt(1 - y^2 - z^2) exceeds |y| and |z|, integrated numerically."""

    def half_width(y: float) -> float:  # the shadow's z extent at y
        return min(math.sqrt(max(1 - 2 * y * y, 0.0)), math.sqrt((1 - y * y) / 2))

    area: float
    area, _ = quad(half_width, 0.0, 1 / math.sqrt(2), points=[1 / math.sqrt(3)], epsabs=1e-12)
    return 4 * area


@pytest.mark.parametrize("receptors", [None, 2_000, 200])
def test_a_still_body_takes_in_berg_and_purcells_flux(receptors: int | None) -> None:
    """Over many windows a still robot's count has the mean 4 pi D a c tau N s / (N s + pi a)
    (Berg & Purcell 1977; the perfect absorber, Smoluchowski's, with no receptors given), and
    the difference of its front and back patches in a linear gradient g is the absorber's
    3 D g cos(theta) over both patches: 2 x 3 D g a^2 tau x the patch's shadow, times
    x / (2 + x) for receptors (x = N s / pi a)."""
    a, d = 1.0, 400.0
    extra = {} if receptors is None else {"receptors": receptors, "receptor_radius_nm": 2.0}
    s = counted(robot_radius_um=a, molecule_diffusion_um2_s=d, **extra)
    p = kernel_params(s)
    tau = s.physics.integration_time_s
    assert tau is not None and p.window * s.physics.step_s == pytest.approx(tau)
    c_nm = 0.05
    c = c_nm * MOLECULES_PER_UM3_PER_NM
    covered = 1.0 if receptors is None else receptors * 2e-3 / (receptors * 2e-3 + math.pi * a)
    x = math.inf if receptors is None else receptors * 2e-3 / (math.pi * a)
    gradient_share = 1.0 if receptors is None else x / (2 + x)
    expected = 4 * math.pi * d * a * c * tau * covered
    g_nm = 0.2 * c_nm / a  # 20 % across the radius
    difference = 2 * 3 * d * g_nm * MOLECULES_PER_UM3_PER_NM * a * a * tau * shadow_of_a_patch()
    difference *= gradient_share
    run = Run(s, kernel_params(s))
    run.swarm.reading_grad[0] = (g_nm, 0.0, 0.0)
    n = 20_000
    out = np.zeros((n, sensing.RECEPTOR_PATCHES))
    _patch_counts(run.params, np.random.default_rng(4), run.swarm, np.full(p.window, c_nm), out)
    total = out.sum(axis=1)
    assert abs(total.mean() - expected) < 4 * math.sqrt(expected / n)
    front_back = out[:, 0] - out[:, 1]
    # the difference's variance is the two Poisson means' sum, about a third of the total's
    sd = math.sqrt(expected / 3 / n)
    assert abs(front_back.mean() - difference) < 4 * sd
    # no gradient across y or z: their patches count alike
    assert abs((out[:, 2] - out[:, 3]).mean()) < 4 * sd


def test_a_count_is_of_the_window_just_past_along_the_path() -> None:
    """A robot that enters the field half-way through a window counts half of what one in it
    throughout counts; a run's first count, at its start, is of a window before it where the
    robot starts, and the next is known when the first step's window ends."""
    s = counted(robot_radius_um=1.0, secretion_molecules_s=1e6)
    p = kernel_params(s)
    per_nm = sensing.RECEPTOR_PATCHES * per_window(p)[0]
    c = 100.0 / per_nm  # 100 molecules a window in the field
    run = Run(s, kernel_params(s))
    n = 20_000
    throughout, entered = np.zeros((n, 6)), np.zeros((n, 6))
    field = np.full(p.window, c)
    _patch_counts(run.params, np.random.default_rng(1), run.swarm, field, throughout)
    field[: p.window // 2] = 0.0
    _patch_counts(run.params, np.random.default_rng(2), run.swarm, field, entered)
    share = (p.window - p.window // 2) / p.window
    assert abs(throughout.sum(axis=1).mean() - 100.0) < 4 * math.sqrt(100.0 / n)
    assert abs(entered.sum(axis=1).mean() - 100.0 * share) < 4 * math.sqrt(100.0 / n)
    # in a run (row k holds what the robot sensed in step k - 1; row 0 is its start): a count
    # from the first step, held for a window, then the next
    t = simulate(s).trajectory
    assert t is not None and t.sensed is not None
    first = t.sensed[1, 0]
    assert first > 0.0 and np.all(t.sensed[1 : p.window + 1, 0] == first)
    assert t.sensed[p.window + 1, 0] != first


@pytest.mark.parametrize(
    ("physics", "field", "words"),
    [
        ({"receptors": 10**6, "receptor_radius_nm": 10.0}, "receptors", "at most 40000"),
        ({"receptor_radius_nm": 2.0}, "receptor_radius_nm", "belongs to receptors"),
        ({"sensor": "each_step", "receptors": 100}, "receptors", "belongs to sensor 'counted'"),
    ],
)
def test_receptors_that_cannot_be_are_refused_naming_them(
    physics: dict[str, Any], field: str, words: str
) -> None:
    with pytest.raises(ValidationError) as raised:
        Scenario.model_validate(
            {"physics": {"model": "active_brownian", "robot_radius_um": 1.0, **physics}}
        )
    error = raised.value.errors()[0]
    assert error["loc"][-1] == field and words in error["msg"], error


@pytest.mark.parametrize("secretion", [1.0, 1e6])
def test_the_blind_tumbler_tumbles_at_its_rate_whatever_it_reads(secretion: float) -> None:
    """No rotational diffusion: the heading changes only where it tumbles, 1 - exp(-rate dt) of
    its steps, in a faint field and in a strong one alike (it uses no information)."""
    s = Scenario.model_validate({
        "physics": {"model": "active_brownian", "robot_radius_um": 1.0, "dt_s": 0.01,
                    "rotational_diffusion_s": 0.0, "diffusion_um2_s": 0.0,
                    "tumble_rate_s": 5.0, "secretion_molecules_s": secretion,
                    "swim_speed_um_s": 1.0, "time_limit_s": 60.0},
        "robots": {"count": 1, "policy": "blind_tumble"}, "space": {"size": 1000.0},
        "obstacles": {"count": 0},
        "learning": {"episodes": 0}, "evaluation": {"worlds": 1}, "seed": 9,
    })  # fmt: skip
    t = simulate(s).trajectory
    assert t is not None and t.headings is not None
    headings = t.headings[:, 0]
    turned = np.any(np.abs(np.diff(headings, axis=0)) > 1e-12, axis=1)
    chance = -math.expm1(-5.0 * 0.01)
    n = len(turned)
    assert n > 5_000
    assert abs(turned.mean() - chance) < 4 * math.sqrt(chance * (1 - chance) / n)
