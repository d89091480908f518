"""Active Brownian motion's parts against theory: Stokes-Einstein(-Debye) figures, the exact
per-step heading correlation, bounded turns, and readings at the Berg-Purcell limit. The
mean squared displacement and the heading correlation at many lags are checked in
tests/benchmarks/test_physics_benchmark.py, which runs benchmarks/physics.py."""

from __future__ import annotations

import math

import numpy as np
import pytest

from nanonav.engine.dynamics import brownian

BODY_K = 310.15
WATER_37C_MPA_S = 0.69


def test_stokes_einstein_gives_the_textbook_figures() -> None:
    # k_B T / (6 pi eta R) by hand: 1.380649e-23 * 310.15 / (6 pi 0.69e-3 1e-6) = 3.2923e-13 m^2/s
    assert brownian.stokes_einstein_um2_s(BODY_K, WATER_37C_MPA_S, 1.0) == pytest.approx(
        0.32923, rel=1e-4
    )
    # k_B T / (8 pi eta R^3): 0.24693 1/s at 1 um, a thousand times more at 0.1 um
    assert brownian.stokes_einstein_debye_s(BODY_K, WATER_37C_MPA_S, 1.0) == pytest.approx(
        0.24693, rel=1e-4
    )
    assert brownian.stokes_einstein_debye_s(BODY_K, WATER_37C_MPA_S, 0.1) == pytest.approx(
        246.93, rel=1e-4
    )
    # Einstein's sphere in water at 20 degrees C (1.002 mPa s): 0.214 um^2/s at 1 um
    assert brownian.stokes_einstein_um2_s(293.15, 1.002, 1.0) == pytest.approx(0.2142, rel=1e-3)
    # for a sphere, D_T / D_R = 4 R^2 / 3 whatever the fluid
    for radius in (0.2, 3.0):
        d_t = brownian.stokes_einstein_um2_s(300.0, 1.3, radius)
        d_r = brownian.stokes_einstein_debye_s(300.0, 1.3, radius)
        assert d_t / d_r == pytest.approx(4 * radius**2 / 3, rel=1e-12)
    # a 0.1 um swimmer at 10 um/s keeps its heading for some 20 nm
    d_r = brownian.stokes_einstein_debye_s(BODY_K, WATER_37C_MPA_S, 0.1)
    assert brownian.persistence_length_um(10.0, d_r) == pytest.approx(0.02025, rel=1e-3)


@pytest.mark.parametrize("rotation", [0.001, 0.05, 0.4])
def test_one_step_of_heading_diffusion_has_the_exact_correlation_and_stays_unit(
    rotation: float,
) -> None:
    # rotation = D_R dt; the mean of n' . n over N independent steps has sd/sqrt(N) error
    sigma = brownian.heading_kick_scale(rotation, 1.0)
    rng = np.random.default_rng(4)
    start = np.array([0.3, -0.5, 0.8])
    start /= np.linalg.norm(start)
    nx, ny, nz = start
    turned = np.array([brownian.diffuse_heading(rng, nx, ny, nz, sigma) for _ in range(100_000)])
    assert np.allclose(np.linalg.norm(turned, axis=1), 1.0, atol=1e-12)
    dots = turned @ start
    error = 4 * np.std(dots) / math.sqrt(len(dots))
    assert abs(np.mean(dots) - math.exp(-2 * rotation)) < error
    # isotropic about n: no direction of the tangent plane is preferred
    tangent = turned - np.outer(dots, start)
    assert np.all(np.abs(tangent.mean(axis=0)) < 4 * tangent.std(axis=0) / math.sqrt(len(dots)))


def test_the_kick_scale_matches_the_small_step_limit_and_refuses_nonsense() -> None:
    # for small D_R dt the rotation angle's mean square 2 sigma^2 is 4 D_R dt
    sigma = brownian.heading_kick_scale(0.25, 1e-4)
    assert 2 * sigma**2 == pytest.approx(4 * 0.25 * 1e-4, rel=1e-3)
    assert brownian.heading_kick_scale(0.0, 0.1) == 0.0
    assert brownian.heading_kick_scale(1e3, 10.0) == pytest.approx(1.3069, rel=1e-3)
    for bad in ((-1.0, 0.1), (1.0, 0.0)):
        with pytest.raises(ValueError):
            brownian.heading_kick_scale(*bad)


def test_a_turn_toward_a_direction_is_bounded_and_stays_in_their_plane() -> None:
    n = (1.0, 0.0, 0.0)
    assert brownian.turn_toward(*n, 0.0, 2.0, 0.0, math.pi) == pytest.approx((0.0, 1.0, 0.0))
    turned = brownian.turn_toward(*n, 0.0, 1.0, 0.0, 0.1)
    assert turned == pytest.approx((math.cos(0.1), math.sin(0.1), 0.0))
    opposite = np.array(brownian.turn_toward(*n, -1.0, 0.0, 0.0, 0.3))
    assert math.acos(float(opposite @ np.array(n))) == pytest.approx(0.3)
    assert brownian.turn_toward(*n, 0.0, 0.0, 0.0, 1.0) == n  # nothing to turn toward
    rng = np.random.default_rng(2)
    for _ in range(200):
        a, b = rng.standard_normal(3), rng.standard_normal(3)
        a /= np.linalg.norm(a)
        (ax, ay, az), (bx, by, bz) = a, b
        out = np.array(brownian.turn_toward(ax, ay, az, bx, by, bz, 0.2))
        assert np.linalg.norm(out) == pytest.approx(1.0)
        assert math.acos(min(1.0, float(out @ a))) <= 0.2 + 1e-9
        assert abs(float(np.cross(a, b) @ out)) < 1e-9  # in the plane of n and t


def test_readings_carry_the_berg_purcell_error_and_it_falls_as_one_over_root_c() -> None:
    # pi D a c tau molecules: 100 um^2/s, a 1 um sensor, 1 nM (0.6022 / um^3), 0.1 s: 18.92
    one = brownian.berg_purcell_relative_error(100.0, 1.0, 1.0, 0.1)
    assert one == pytest.approx(1 / math.sqrt(math.pi * 100 * 1 * 0.602214076 * 0.1), rel=1e-9)
    assert brownian.berg_purcell_relative_error(100.0, 1.0, 4.0, 0.1) == pytest.approx(one / 2)
    assert brownian.berg_purcell_relative_error(100.0, 1.0, 0.0, 0.1) == math.inf
    rng = np.random.default_rng(9)
    for concentration in (1.0, 4.0):
        relative = brownian.berg_purcell_relative_error(100.0, 1.0, concentration, 0.1)
        draws = np.array([brownian.read_concentration(rng, concentration, relative)
                          for _ in range(50_000)])  # fmt: skip
        assert draws.min() >= 0.0
        n = len(draws)
        assert np.mean(draws) == pytest.approx(
            concentration, abs=4 * relative * concentration / n**0.5
        )
        se = relative * 0.5 * math.sqrt((2 + 6 * relative**2) / n)  # a gamma law's sample sd
        assert abs(np.std(draws) / concentration - relative) < 4 * se
    assert brownian.read_concentration(rng, 0.0, 0.5) == 0.0
    assert brownian.read_concentration(rng, 2.5, 0.0) == 2.5
