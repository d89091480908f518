"""The active Brownian physics checked against theory: every figure simulated beside its formula,
with the 95 % interval of the simulated value (from the sample of independent robots).

    python benchmarks/physics.py [--robots N] [--quick]

Checks, in water at 37 degrees C (viscosity 0.69 mPa s):
1. Stokes-Einstein(-Debye): D_T and D_R of spheres of 0.1, 1 and 5 um.
2. Passive Brownian motion (speed 0): the mean squared displacement is 6 D_T t.
3. Active Brownian motion (10 um/s, R = 1 um): the MSD follows
   6 D_T t + (v^2 / D_R) [t - (1 - exp(-2 D_R t)) / (2 D_R)], and the heading correlation
   exp(-2 D_R t), at several lags.
4. Sensing at the Berg-Purcell limit: the relative sd of readings at two concentrations.

A check passes when the theory lies within four standard errors of the simulated value, plus the
known bias of a step of dt (the Euler scheme's MSD is a sum over steps, not the integral; printed
as 'bias' where it is not zero).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from nanonav.engine.dynamics import brownian

TEMPERATURE_K = 310.15  # 37 degrees C
VISCOSITY_MPA_S = 0.69  # water at 37 degrees C


@dataclass(frozen=True)
class Check:
    """One simulated figure beside its theory."""

    name: str
    lag_s: float | None
    simulated: float
    standard_error: float
    theory: float
    bias: float = 0.0  # the expected gap between simulated and theory from the step size

    @property
    def passed(self) -> bool:
        return abs(self.simulated - self.theory) <= 4.0 * self.standard_error + abs(self.bias)

    def line(self) -> str:
        low = self.simulated - 1.96 * self.standard_error
        high = self.simulated + 1.96 * self.standard_error
        lag = "" if self.lag_s is None else f" at t = {self.lag_s:g} s"
        bias = f", bias {self.bias:+.3g}" if abs(self.bias) > 1e-9 * abs(self.theory) else ""
        return (
            f"  {self.name}{lag}: simulated {self.simulated:.4g} [{low:.4g}, {high:.4g}], "
            f"theory {self.theory:.4g}, ratio {self.simulated / self.theory:.4f}{bias}"
            f"  {'ok' if self.passed else 'FAILED'}"
        )


def swimmers(
    robots: int,
    steps: int,
    record_every: int,
    speed_um_s: float,
    radius_um: float,
    dt_s: float,
    seed: int,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Positions and headings of free swimmers every ``record_every`` steps, rows from t = 0."""
    d_t = brownian.stokes_einstein_um2_s(TEMPERATURE_K, VISCOSITY_MPA_S, radius_um)
    d_r = brownian.stokes_einstein_debye_s(TEMPERATURE_K, VISCOSITY_MPA_S, radius_um)
    sigma = brownian.heading_kick_scale(d_r, dt_s)
    rng = np.random.default_rng(seed)
    pos = np.zeros((robots, 3))
    heading = rng.standard_normal((robots, 3))
    heading /= np.linalg.norm(heading, axis=1, keepdims=True)
    active = np.ones(robots, dtype=np.bool_)
    positions = [pos.copy()]
    headings = [heading.copy()]
    for _ in range(steps // record_every):
        for _ in range(record_every):
            brownian.swim(rng, pos, heading, active, speed_um_s, d_t, sigma, dt_s)
        positions.append(pos.copy())
        headings.append(heading.copy())
    return np.array(positions), np.array(headings)


def euler_msd_um2(d_t: float, speed: float, d_r: float, dt_s: float, steps: int) -> float:
    """The MSD the Euler scheme gives after ``steps`` steps exactly: 6 D_T k dt plus
    v^2 dt^2 sum_ij rho^|i-j|, with rho = exp(-2 D_R dt) the per-step heading correlation."""
    rho = math.exp(-2.0 * d_r * dt_s)
    m = np.arange(1, steps)
    pairs = steps + 2.0 * float(np.sum((steps - m) * rho**m))
    return 6.0 * d_t * steps * dt_s + (speed * dt_s) ** 2 * pairs


def msd_checks(
    label: str, positions: NDArray[np.float64], lags: list[int], dt_s: float, record_every: int,
    d_t: float, speed: float, d_r: float,
) -> list[Check]:  # fmt: skip
    checks = []
    for row in lags:
        squared = np.sum((positions[row] - positions[0]) ** 2, axis=1)
        steps = row * record_every
        t = steps * dt_s
        theory = brownian.mean_squared_displacement_um2(d_t, speed, d_r, t)
        bias = euler_msd_um2(d_t, speed, d_r, dt_s, steps) - theory
        se = float(np.std(squared, ddof=1) / math.sqrt(len(squared)))
        checks.append(Check(f"{label} MSD (um^2)", t, float(np.mean(squared)), se, theory, bias))
    return checks


def all_checks(robots: int, seed: int = 1) -> list[Check]:
    checks: list[Check] = []
    # 1. Stokes-Einstein(-Debye), against the formula written out here in SI
    kt = brownian.BOLTZMANN_J_K * TEMPERATURE_K
    eta = VISCOSITY_MPA_S * 1e-3
    for radius in (0.1, 1.0, 5.0):
        r = radius * 1e-6
        d_t = brownian.stokes_einstein_um2_s(TEMPERATURE_K, VISCOSITY_MPA_S, radius)
        d_r = brownian.stokes_einstein_debye_s(TEMPERATURE_K, VISCOSITY_MPA_S, radius)
        # exact formulas: equal to rounding (1e-12 of the value stands for the error)
        checks.append(Check(f"D_T (um^2/s), R = {radius} um", None, d_t, 1e-12 * d_t,
                            kt / (6 * math.pi * eta * r) * 1e12))  # fmt: skip
        checks.append(Check(f"D_R (1/s), R = {radius} um", None, d_r, 1e-12 * d_r,
                            kt / (8 * math.pi * eta * r**3)))  # fmt: skip

    # 2. passive: R = 1 um, dt 0.01 s, lags 0.1, 1, 5 s
    radius, dt, every = 1.0, 0.01, 10
    d_t = brownian.stokes_einstein_um2_s(TEMPERATURE_K, VISCOSITY_MPA_S, radius)
    d_r = brownian.stokes_einstein_debye_s(TEMPERATURE_K, VISCOSITY_MPA_S, radius)
    positions, _ = swimmers(robots, 500, every, 0.0, radius, dt, seed)
    checks += msd_checks("passive", positions, [1, 10, 50], dt, every, d_t, 0.0, d_r)

    # 3. active: 10 um/s, R = 1 um (D_R 0.25 1/s, persistence 20 um), lags 0.5 s to 10 s
    speed = 10.0
    positions, headings = swimmers(robots, 1000, every, speed, radius, dt, seed + 1)
    checks += msd_checks("active", positions, [5, 20, 50, 100], dt, every, d_t, speed, d_r)
    for row in (5, 20, 50, 100):
        dots = np.sum(headings[row] * headings[0], axis=1)
        t = row * every * dt
        se = float(np.std(dots, ddof=1) / math.sqrt(len(dots)))
        checks.append(Check("heading correlation", t, float(np.mean(dots)), se,
                            brownian.heading_correlation(d_r, t)))  # fmt: skip
    # a small robot: R = 0.2 um, D_R 31 1/s, so the heading decorrelates within 0.05 s
    small = 0.2
    d_r_small = brownian.stokes_einstein_debye_s(TEMPERATURE_K, VISCOSITY_MPA_S, small)
    _, headings = swimmers(robots, 100, 1, speed, small, 1e-4, seed + 2)
    for row in (10, 50, 100):
        dots = np.sum(headings[row] * headings[0], axis=1)
        t = row * 1e-4
        se = float(np.std(dots, ddof=1) / math.sqrt(len(dots)))
        checks.append(Check(f"heading correlation, R = {small} um", t, float(np.mean(dots)), se,
                            brownian.heading_correlation(d_r_small, t)))  # fmt: skip

    # 4. readings at the Berg-Purcell limit: a 1 um sensor, a protein (D 100 um^2/s), 0.1 s
    rng = np.random.default_rng(seed + 3)
    for concentration in (1.0, 4.0):
        relative = brownian.berg_purcell_relative_error(100.0, 1.0, concentration, 0.1)
        draws = np.array([brownian.read_concentration(rng, concentration, relative)
                          for _ in range(robots * 10)])  # fmt: skip
        sd = float(np.std(draws, ddof=1) / np.mean(draws))
        # the sample sd's standard error, for a gamma law (excess kurtosis 6 r^2)
        se = sd * 0.5 * math.sqrt((2.0 + 6.0 * relative**2) / len(draws))
        checks.append(Check(f"relative sd of readings at {concentration:g} nM", None, sd, se,
                            relative))  # fmt: skip
    return checks


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--robots", type=int, default=20_000, help="independent robots per check")
    parser.add_argument("--quick", action="store_true", help="a smoke run: 2,000 robots")
    args = parser.parse_args(argv)
    robots = 2_000 if args.quick else args.robots
    started = time.perf_counter()
    checks = all_checks(robots)
    print(f"Active Brownian physics against theory ({robots} robots per check; 95 % intervals)")
    for check in checks:
        print(check.line())
    failed = [c for c in checks if not c.passed]
    print(f"{len(checks) - len(failed)} of {len(checks)} checks within 4 standard errors "
          f"({time.perf_counter() - started:.0f} s)")  # fmt: skip
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
