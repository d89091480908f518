"""The physics the scenario and the engine both rely on, as pure functions: a sphere's
diffusion in a fluid (Stokes-Einstein and Stokes-Einstein-Debye), the time a molecule takes to
cross a body, and the bounds a time step must keep. SI constants exact since 2019; lengths in
µm, times in s."""

from __future__ import annotations

import math

BOLTZMANN_J_K = 1.380649e-23  # exact since the 2019 SI
AVOGADRO_PER_MOL = 6.02214076e23  # exact since the 2019 SI
MOLECULES_PER_UM3_PER_NM = AVOGADRO_PER_MOL * 1e-9 / 1e15  # 1 nM in molecules per µm³: 0.6022


def stokes_einstein_um2_s(temperature_k: float, viscosity_mpa_s: float, radius_um: float) -> float:
    """D_T = k_B T / (6 pi eta R) of a sphere, µm²/s."""
    return (
        BOLTZMANN_J_K
        * temperature_k
        / (6 * math.pi * viscosity_mpa_s * 1e-3 * radius_um * 1e-6)
        * 1e12
    )


def stokes_einstein_debye_s(
    temperature_k: float, viscosity_mpa_s: float, radius_um: float
) -> float:
    """D_R = k_B T / (8 pi eta R^3) of a sphere, 1/s."""
    return (
        BOLTZMANN_J_K
        * temperature_k
        / (8 * math.pi * viscosity_mpa_s * 1e-3 * (radius_um * 1e-6) ** 3)
    )


LARGEST_AUTOMATIC_DT_S = 0.01
DT_FLOOR_S = 1e-9  # the finest time step: within the bounds no motion needs a finer one


def time_step_bounds(
    d_t: float, d_r: float, speed: float, radius: float, dt: float
) -> list[tuple[float, float, float, str]]:
    """Each bound a time step must keep: (its value at dt, the largest allowed, the dt that
    reaches it, what breaking it means)."""
    half = radius / 2
    return [
        (d_r * dt, 0.05, 0.05 / d_r if d_r else math.inf,
         "the heading would turn by D_R dt = {value:.3g} per step (at most 0.05)"),
        (speed * dt, half, half / speed if speed else math.inf,
         "a step would swim {value:.3g} µm, over half of robot_radius_um"),
        (math.sqrt(2 * d_t * dt), half, half**2 / (2 * d_t) if d_t else math.inf,
         "a step would jiggle sqrt(2 D_T dt) = {value:.3g} µm, over half of robot_radius_um"),
    ]  # fmt: skip


def automatic_dt_s(d_t: float, d_r: float, speed: float, radius: float) -> float:
    """The time step that validation fills in: the largest that keeps every bound, at most
    0.01 s, two significant figures rounded down."""
    fine = min(b[2] for b in time_step_bounds(d_t, d_r, speed, radius, 0.0))
    return min(LARGEST_AUTOMATIC_DT_S, float(rounded_down(fine)))


def time_limit_steps(time_limit_s: float, dt_s: float) -> int:
    """learning.max_steps of a time limit: ceil(time_limit_s / dt_s), and at least one step."""
    return max(1, math.ceil(time_limit_s / dt_s - 1e-9))


def crossing_time_s(radius_um: float, molecule_diffusion_um2_s: float) -> float:
    """r^2 / D_m: the time a molecule takes to diffuse across a body of radius r, s; two counts
    closer in time than it count many of the same molecules (Berg & Purcell 1977)."""
    return radius_um**2 / molecule_diffusion_um2_s


def rounded_down(value: float) -> str:
    """A time step to suggest: two significant figures, rounded down so that it keeps the bound."""
    if not math.isfinite(value) or value <= 0:
        return f"{value:g}"
    scale = 10 ** (math.floor(math.log10(value)) - 1)
    return f"{math.floor(value / scale) * scale:.3g}"
