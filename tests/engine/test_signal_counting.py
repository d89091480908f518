"""Signals counted as the biomarker is (sensor 'counted'): each species' molecules that the six
receptor patches took in over the window just past, Poisson, known at the window's end and held
until the next; the net signal is the attractant's count less the repellent's."""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from nanonav.engine import communication, sensing
from nanonav.engine.simulation import Run, kernel_params
from nanonav.engine.state import KernelParams, Social
from nanonav.scenario import Scenario, preset_scenario


def signalling(model: str = "attractant", sensor: str = "counted") -> Scenario:
    return preset_scenario(
        "tumour-signals", seed=4, robots={"count": 1},
        physics={"sensor": sensor}, communication={"model": model},
        learning={"episodes": 0}, evaluation={"worlds": 1},
    )  # fmt: skip


@njit(cache=True)
def _windows(
    p: KernelParams, rng: np.random.Generator, grid: NDArray[np.float64],
    pos: NDArray[np.float64], so: Social, patches: NDArray[np.float64],
    nets: NDArray[np.float64], gradients: NDArray[np.float64],
) -> None:  # fmt: skip
    """Robot 0, still, listens window after window: each window's six patch counts of the
    attractant (drawn as the engine draws them, from what the window took in), and the net
    signal and gradient it holds after ``listen`` counted them."""
    for j in range(nets.shape[0]):
        for _ in range(p.window):
            communication.take_in_signal(p, grid, pos, so, 0, 1.0)
        copy = so.signal_flux[0].copy()
        for k in range(sensing.RECEPTOR_PATCHES):
            patches[j, k] = sensing.poisson_count(rng, copy[k])
        communication.count_signal(p, rng, grid.shape[0], so, 0)
        nets[j] = so.signal[0]
        for k in range(3):
            gradients[j, k] = so.signal_grad[0, k]


def listened(
    run: Run, field: NDArray[np.float64], n: int
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """``n`` windows of a still robot at the grid's centre in ``field`` (the attractant's)."""
    run.signals.conc[0] = field
    pos = np.zeros((1, 3))
    patches, nets, gradients = np.zeros((n, 6)), np.zeros(n), np.zeros((n, 3))
    _windows(run.params, np.random.default_rng(9), run.signals.conc, pos, run.social,
             patches, nets, gradients)  # fmt: skip
    return patches, nets, gradients


def test_a_signal_is_a_poisson_count_of_a_window_of_molecules() -> None:
    run = Run(signalling(), kernel_params(signalling()))
    p = run.params
    per_window = sensing.RECEPTOR_PATCHES * p.window * p.signal_patch_rate  # molecules per nM
    c = 30.0 / per_window  # 30 molecules a window
    n = 20_000
    patches, nets, gradients = listened(run, np.full(run.signals.conc.shape[1:], c), n)
    counts = nets * per_window
    # whole numbers of molecules, Poisson: mean and variance 30, and 0 as often as e^-30
    assert np.allclose(counts, np.round(counts))
    assert abs(counts.mean() - 30.0) < 4 * math.sqrt(30.0 / n)
    assert abs(counts.var(ddof=1) / 30.0 - 1) < 4 * math.sqrt(2 / n)
    # each patch a sixth, the patches independent: their counts do not correlate
    assert abs(patches.mean() - 5.0) < 4 * math.sqrt(5.0 / patches.size)
    assert abs(np.corrcoef(patches[:, 0], patches[:, 1])[0, 1]) < 4 / math.sqrt(n)
    # in a uniform field the gradient is the patches' difference alone, of mean 0
    assert np.all(np.abs(gradients.mean(axis=0)) < 4 * gradients.std(axis=0) / math.sqrt(n))


def test_a_signals_gradient_is_its_patches_difference_in_a_linear_field() -> None:
    run = Run(signalling(), kernel_params(signalling()))
    p = run.params
    dims, origin, spacing = p.signal_dims, p.signal_origin, p.signal_spacing
    x = origin + spacing * np.arange(dims)
    per_window = sensing.RECEPTOR_PATCHES * p.window * p.signal_patch_rate
    c = 200.0 / per_window
    g = c / 40.0  # nM/um, along x
    field = np.broadcast_to((c + g * x)[:, None, None], (dims, dims, dims)).copy()
    n = 20_000
    patches, _, gradients = listened(run, field, n)
    front_back = patches[:, 0] - patches[:, 1]
    expected = 2 * p.window * p.signal_patch_gradient_rate * g
    sd = front_back.std() / math.sqrt(n)
    assert expected > 10 * sd  # the test can tell the gradient from none
    assert abs(front_back.mean() - expected) < 4 * sd
    assert abs(gradients[:, 0].mean() - g) < 4 * gradients[:, 0].std() / math.sqrt(n)
    assert abs(gradients[:, 1].mean()) < 4 * gradients[:, 1].std() / math.sqrt(n)


def test_a_repellent_counts_against_the_attractant() -> None:
    scenario = signalling("attractant_repellent")
    run = Run(scenario, kernel_params(scenario))
    p = run.params
    per_window = sensing.RECEPTOR_PATCHES * p.window * p.signal_patch_rate
    run.signals.conc[0] = 20.0 / per_window
    run.signals.conc[1] = 50.0 / per_window
    n = 10_000
    nets = np.zeros(n)
    _windows(p, np.random.default_rng(3), run.signals.conc, np.zeros((1, 3)), run.social,
             np.zeros((n, 6)), nets, np.zeros((n, 3)))  # fmt: skip
    # attractant minus repellent: mean -30 molecules, variance 20 + 50
    counts = nets * per_window
    assert abs(counts.mean() + 30.0) < 4 * math.sqrt(70.0 / n)
    assert abs(counts.var(ddof=1) / 70.0 - 1) < 4 * math.sqrt(2 / n)


@njit(cache=True)
def _listen_steps(
    p: KernelParams, rng: np.random.Generator, grid: NDArray[np.float64],
    pos: NDArray[np.float64], so: Social, on_at: int, steps: int, out: NDArray[np.float64],
    value: float,
) -> None:  # fmt: skip
    """Robot 0 listens for ``steps`` steps; the attractant is 0 until step ``on_at``, then
    ``value`` everywhere; ``out[t]`` is what it holds in step t."""
    for t in range(steps):
        if t == on_at:
            grid[0, :, :, :] = value
        communication.listen(p, rng, grid, pos, so, 0, 0.0)
        out[t] = so.signal[0]


def test_a_signal_is_known_when_its_window_ends_and_held_until_the_next() -> None:
    """A field that appears mid-window is not heard until that window ends, and then as a
    part of a window's count; the count is held for a window."""
    scenario = signalling()
    p = kernel_params(scenario)
    w = p.window
    per_window = sensing.RECEPTOR_PATCHES * w * p.signal_patch_rate
    value = 1e4 / per_window  # 10,000 molecules a window: a count's sd is 1 %
    half = w // 2
    n = 200
    seen = np.zeros((n, 3 * w))
    for k in range(n):
        run = Run(scenario, p)
        _listen_steps(p, np.random.default_rng(k), run.signals.conc, np.zeros((1, 3)),
                      run.social, w + half, 3 * w, seen[k], value)  # fmt: skip
    # counts come at steps 0 (a window where it starts), w (of steps 0..w-1) and 2w (of steps
    # w..2w-1): the field, there from step w + half, is heard at 2w and not before
    assert np.all(seen[:, : 2 * w] == 0.0)
    share = (w - half) / w  # of the window 2w ends
    at_end = seen[:, 2 * w]
    assert abs(at_end.mean() / value - share) < 4 * math.sqrt(share * 1e4) / 1e4 / math.sqrt(n)
    assert np.all(seen[:, 2 * w :] == at_end[:, None])  # held for its window


def test_the_each_step_sensor_still_reads_signals_each_step() -> None:
    scenario = signalling(sensor="each_step")
    p = kernel_params(scenario)
    assert p.signal_patch_rate == 0.0 and p.signal_counting > 0.0
    run = Run(scenario, p)
    out = np.zeros(8)
    _listen_steps(p, np.random.default_rng(0), run.signals.conc, np.zeros((1, 3)), run.social,
                  0, 8, out, 5.0)  # fmt: skip
    assert np.all(out > 0.0) and len(set(out.tolist())) == 8  # a fresh reading every step
