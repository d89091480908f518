"""The scenario's physics part: the paper's lattice or active Brownian motion in SI units, and
what validation fills in of the latter (``fill_physics``)."""

from __future__ import annotations

import math
from typing import Any

from pydantic import (
    Field,
    model_validator,
)

from nanonav.physics import (
    DT_FLOOR_S,
    automatic_dt_s,
    crossing_time_s,
    rounded_down,
    stokes_einstein_debye_s,
    stokes_einstein_um2_s,
    time_limit_steps,
    time_step_bounds,
)
from nanonav.scenario.base import Part, admits, field_error
from nanonav.scenario.choices import PhysicsModel, Sensor
from nanonav.scenario.limits import DEFAULT_INTEGRATION_TIME_S, MAX_STEPS


def fill_physics(data: Any) -> Any:
    """An active Brownian physics section with what it leaves out filled in: D_T and D_R from
    Stokes-Einstein(-Debye), dt_s the largest step that keeps every bound (``automatic_dt_s``).
    Only what is derived from values within their fields' bounds is filled in (the bounds keep
    it finite and within its own); anything else is returned as it came, for validation to
    refuse. Never raises."""
    if not isinstance(data, dict) or data.get("model") != "active_brownian":
        return data
    fields = Physics.model_fields
    stokes = ("temperature_k", "viscosity_mpa_s", "robot_radius_um", "swim_speed_um_s")
    got = {k: data.get(k, fields[k].default) for k in stokes}
    if not all(admits(Physics, k, got[k]) for k in stokes):
        return data  # the fields' own validation says what is wrong
    t, eta, r, v = (float(got[k]) for k in stokes)
    filled = dict(data)
    if filled.get("diffusion_um2_s") is None:
        filled["diffusion_um2_s"] = stokes_einstein_um2_s(t, eta, r)
    if filled.get("rotational_diffusion_s") is None:
        filled["rotational_diffusion_s"] = stokes_einstein_debye_s(t, eta, r)
    d_t, d_r = filled["diffusion_um2_s"], filled["rotational_diffusion_s"]
    if (
        filled.get("dt_s") is None
        and admits(Physics, "diffusion_um2_s", d_t)
        and admits(Physics, "rotational_diffusion_s", d_r)
    ):
        filled["dt_s"] = automatic_dt_s(float(d_t), float(d_r), v, r)
    d_m = data.get("molecule_diffusion_um2_s", fields["molecule_diffusion_um2_s"].default)
    if (
        filled.get("sensor", fields["sensor"].default) == "counted"
        and filled.get("integration_time_s") is None
        and admits(Physics, "molecule_diffusion_um2_s", d_m)
    ):
        filled["integration_time_s"] = max(DEFAULT_INTEGRATION_TIME_S, crossing_time_s(r, d_m))
    return filled


class Physics(Part):
    """How robots, cells and molecules move. 'lattice' (the paper's, the default): a robot moves
    exactly robots.speed along the direction its policy chooses, every step. 'active_brownian':
    a sphere of robot_radius_um swims at swim_speed_um_s along a heading that diffuses, jiggles
    with translational diffusion, and can only steer (at most max_turn_rate_rad_s); the field is
    the steady state of what each cell secretes, read at the Berg-Purcell limit. Every quantity
    below belongs to 'active_brownian' (and is refused with 'lattice'); the documentation's
    physics page (docs/explanation/physics.md) gives each default's source. The bounds are
    physical, and hold what is derived from them (D_T, D_R, dt_s, the step limit) finite and
    within its own: each says why in its description."""

    model: PhysicsModel = Field(
        "lattice",
        description="'lattice' (the paper's model, in simulation units and steps) or "
        "'active_brownian' (SI: µm, s, nM; every length of the scenario is then in µm).",
    )
    dt_s: float | None = Field(
        None,
        ge=DT_FLOOR_S,
        le=10.0,
        description="Time step, s. It must resolve the motion: the heading may turn by "
        "D_R dt <= 0.05 per step, and a step (swimming or jiggling) may cover at most half of "
        "robot_radius_um; a coarser step is refused with the dt_s that would do. null: the "
        "largest such step, at most 0.01 s, filled in in the resolved scenario (so a study "
        "over robot_radius_um gets a fitting step at every radius). At least 1e-9 s: within "
        "the other fields' bounds no motion needs a finer step (the finest, 1.2e-9 s, is for "
        "a 10 nm robot whose D_T is 1e4 µm²/s).",
    )
    time_limit_s: float | None = Field(
        None,
        ge=DT_FLOOR_S,
        le=1e6,
        description="The episode's time limit, s: learning.max_steps becomes ceil(time_limit_s "
        "/ dt_s) (at least 1, at most 1,000,000: a longer limit is refused), filled in. null: "
        "learning.max_steps steps of dt_s. At least 1e-9 s, dt_s's floor.",
    )
    temperature_k: float = Field(
        310.15, ge=250.0, le=400.0, description="Temperature, K (37 degrees C: the body's)."
    )
    viscosity_mpa_s: float = Field(
        0.69,
        ge=0.01,
        le=1e5,
        description="Viscosity of the fluid, mPa s (water at 37 degrees C: 0.69; interstitial "
        "fluid is close to water, a mucus or matrix far more). From 0.01, a gas's (air: "
        "0.018), to 1e5 (100 Pa s, a thick mucus).",
    )
    robot_radius_um: float = Field(
        1.0,
        ge=0.01,
        le=50.0,
        description="Radius of a (spherical) robot, µm: from 10 nm, a small nanoparticle, to "
        "50 µm.",
    )
    swim_speed_um_s: float = Field(
        10.0,
        ge=0.0,
        le=1000.0,
        description="Self-propulsion speed along the heading, µm/s (0: a passive Brownian "
        "particle).",
    )
    max_turn_rate_rad_s: float = Field(
        10.0,
        ge=0.0,
        le=1e4,
        description="The fastest a robot can steer its heading, rad/s; a tumble is a random new "
        "heading and not bound by it.",
    )
    diffusion_um2_s: float | None = Field(
        None,
        ge=0.0,
        le=1e4,
        description="Translational diffusion D_T, µm²/s. null: Stokes-Einstein, "
        "k_B T / (6 pi eta R), filled in in the resolved scenario. At most 1e4, above any "
        "Stokes-Einstein value the other bounds allow (2,930: 10 nm, 0.01 mPa s, 400 K).",
    )
    rotational_diffusion_s: float | None = Field(
        None,
        ge=0.0,
        le=2.5e7,
        description="Rotational diffusion D_R, 1/s: the heading correlation decays as "
        "exp(-2 D_R t). null: Stokes-Einstein-Debye, k_B T / (8 pi eta R^3), filled in in the "
        "resolved scenario. At most 2.5e7, above any Stokes-Einstein-Debye value the other "
        "bounds allow (2.2e7: 10 nm, 0.01 mPa s, 400 K) and resolved by a step of 2e-9 s.",
    )
    cell_radius_um: float = Field(
        7.5,
        ge=0.5,
        le=100.0,
        description="Radius of a cancer cell, µm; a robot reaches a cell when its surface "
        "touches the cell's. At least 0.5 µm, a bacterium's: no cell is smaller.",
    )
    cell_diffusion_um2_s: float = Field(
        0.005,
        ge=0.0,
        le=100.0,
        description="Cells move as a random walk with this diffusion coefficient, µm²/s "
        "(0.005: about 1.3 µm a minute).",
    )
    secretion_molecules_s: float = Field(
        100.0,
        ge=1.0,
        le=1e9,
        description="Biomarker molecules a cell secretes per second, at least one (a cell "
        "secretes a cytokine at tens to thousands a second).",
    )
    molecule_diffusion_um2_s: float = Field(
        100.0,
        ge=0.01,
        le=1e4,
        description="Diffusion coefficient of the biomarker molecule, µm²/s (about 100 for a "
        "small protein, 60 for an antibody). At least 0.01, a 30 µm bead's in water: every "
        "molecule diffuses faster.",
    )
    decay_rate_s: float = Field(
        0.01,
        ge=1e-6,
        le=1e3,
        description="Rate at which the biomarker is cleared or decays, 1/s. The field of a cell "
        "is Q exp(-r/lambda) / (4 pi D_m r) with lambda = sqrt(D_m / decay_rate_s). At least "
        "1e-6, a lifetime of 1e6 s (the longest time_limit_s): slower is no decay in a run.",
    )
    tumble_rate_s: float = Field(
        1.0,
        ge=0.0,
        le=1e4,
        description="run_and_tumble and steer_and_tumble: tumbles per second while the reading "
        "does not rise; blind_tumble: tumbles per second, always.",
    )
    tumble_rate_rising_s: float = Field(
        0.25,
        ge=0.0,
        le=1e4,
        description="run_and_tumble and steer_and_tumble: tumbles per second while the reading "
        "rises (fewer: runs up "
        "the gradient last longer).",
    )
    memory_s: float = Field(
        1.0,
        ge=0.0,
        le=1e4,
        description="Temporal sensing: a reading is compared with the mean of the robot's "
        "readings over this past time to tell whether it rises (0: with the last reading).",
    )
    short_memory_s: float = Field(
        0.0,
        ge=0.0,
        le=1e4,
        description="Temporal sensing on two time scales: what is compared with the mean over "
        "memory_s is the mean of the robot's readings over this shorter past time (an "
        "exponential average, as memory_s's), so that a rise is told from a few noisy counts "
        "rather than one; the rules that tumble and the Q-learner's 'rising' use it. Less than "
        "memory_s. 0: the reading itself.",
    )
    sensor: Sensor = Field(
        "counted",
        description="How a robot reads the biomarker. 'counted': molecules counted, Poisson, "
        "by six receptor patches (each a sixth of the surface, facing the axes' two ways) over "
        "integration_time_s; the reading is their sum, the gradient their differences, both "
        "held until the next count (so a reading is 0 where molecules are scarce, and what a "
        "robot learns of the field does not grow as dt_s shrinks). 'each_step', the default "
        "before molecules were counted: every step a reading of the whole body over dt_s at "
        "the Berg-Purcell limit (a gamma draw of mean the concentration, never 0) and, for "
        "the gradient, one such reading at each end of each axis; what it finds moves with "
        "dt_s.",
    )
    integration_time_s: float | None = Field(
        None,
        ge=1e-6,
        le=100.0,
        description="sensor 'counted': the time over which a count is taken, s, a whole "
        "number of steps of dt_s (rounded to the nearest). At least r^2 / D_m, the time a "
        "molecule takes to cross the body (Berg & Purcell 1977: counts closer in time are not "
        "independent), and at least dt_s. null: 0.1 s (Alonso & Kirkegaard 2024's receptors "
        "count over 0.1 s) or r^2 / D_m if that is longer, filled in in the resolved scenario.",
    )
    receptors: int | None = Field(
        None,
        ge=1,
        le=10**9,
        description="sensor 'counted': the receptors on the body's surface, each a disc of "
        "receptor_radius_nm. The body takes in N s / (N s + pi a) of a perfect absorber's "
        "4 pi D_m a c molecules a second (Berg & Purcell 1977), and the gradient's share of "
        "them as a uniformly absorbing surface of that rate would (docs/explanation/"
        "sensing.md). They must fit on the surface (N s^2 <= 4 a^2). null: a perfectly "
        "absorbing body, the limit of many receptors, the most any body of its size can count.",
    )
    receptor_radius_nm: float = Field(
        1.0,
        ge=0.01,
        le=1000.0,
        description="sensor 'counted', with receptors: a receptor's radius, nm (Berg & Purcell "
        "1977 take about 1 nm for a bacterium's).",
    )
    gradient_memory_s: float = Field(
        0.0,
        ge=0.0,
        le=1e4,
        description="sensor 'counted': the gradient a robot steers by is the exponential "
        "average of its counts' gradients over this past time, s (each count weighs "
        "integration_time_s / gradient_memory_s, at most 1), so that a rule steers by what "
        "several counts agree on rather than by each count's noise; the reading's own memory "
        "is memory_s. 0: the last count's gradient alone.",
    )

    @property
    def step_s(self) -> float:
        """dt_s, which validation fills in for active Brownian motion (0 for the lattice)."""
        return self.dt_s or 0.0

    @model_validator(mode="before")
    @classmethod
    def _stokes(cls, data: Any) -> Any:
        """D_T and D_R default to Stokes-Einstein(-Debye), and dt_s to the largest step that
        resolves the motion, filled in so the resolved scenario shows what ran."""
        return fill_physics(data)

    @model_validator(mode="after")
    def _resolves_the_motion(self) -> Physics:
        if self.model != "active_brownian":
            fields = type(self).model_fields
            changed = [k for k in fields if k != "model" and getattr(self, k) != fields[k].default]
            if changed:
                raise field_error(
                    "Physics", (changed[0],), getattr(self, changed[0]),
                    "belongs to physics.model 'active_brownian'; the lattice physics has no use "
                    "for it",
                )  # fmt: skip
            return self
        dt = self.dt_s or 0.0
        bounds = time_step_bounds(
            self.diffusion_um2_s or 0.0, self.rotational_diffusion_s or 0.0,
            self.swim_speed_um_s, self.robot_radius_um, dt,
        )  # fmt: skip
        fine = min(b[2] for b in bounds)  # a dt that keeps every bound
        for value, largest, _, message in bounds:
            if value > largest * (1 + 1e-12):
                raise field_error(
                    "Physics", ("dt_s",), self.dt_s,
                    f"dt_s {dt:g} s is too coarse: " + message.format(value=value)
                    + f"; dt_s <= {rounded_down(fine)} s would do",
                )  # fmt: skip
        self._sensing_fits(dt)
        return self._time_limit_fits()

    def _sensing_fits(self, dt: float) -> None:
        """The short memory is shorter than the long; integration_time_s and gradient_memory_s
        belong to sensor 'counted', and the integration time is at least the time a molecule
        takes to cross the body and a step."""
        if self.short_memory_s and self.short_memory_s >= self.memory_s:
            raise field_error(
                "Physics", ("short_memory_s",), self.short_memory_s,
                f"must be shorter than memory_s ({self.memory_s:g} s), the mean it is compared "
                "with",
            )  # fmt: skip
        if self.gradient_memory_s and self.sensor != "counted":
            raise field_error(
                "Physics", ("gradient_memory_s",), self.gradient_memory_s,
                "belongs to sensor 'counted' (sensor 'each_step' reads the gradient anew each "
                "step)",
            )  # fmt: skip
        if self.receptors is not None or self.receptor_radius_nm != 1.0:
            self._receptors_fit()
        tau = self.integration_time_s
        if tau is None:
            return
        crossing = crossing_time_s(self.robot_radius_um, self.molecule_diffusion_um2_s)
        if self.sensor != "counted":
            problem = "belongs to sensor 'counted' (sensor 'each_step' reads over each step)"
        elif tau < crossing * (1 - 1e-12):
            problem = (
                f"{tau:g} s is shorter than r^2 / D_m = {crossing:.3g} s, the time a molecule "
                "takes to cross the body: counts closer in time are not independent; "
                f"integration_time_s >= {crossing:.3g} s would do"
            )
        elif tau < dt * (1 - 1e-12):
            problem = f"{tau:g} s is shorter than a step (dt_s {dt:g} s): a count takes whole steps"
        else:
            return
        raise field_error("Physics", ("integration_time_s",), tau, problem)

    def _receptors_fit(self) -> None:
        """Receptors belong to sensor 'counted' (and their radius to receptors), and fit on the
        body: their discs cover at most its surface."""
        field = "receptors" if self.receptors is not None else "receptor_radius_nm"
        value = self.receptors if self.receptors is not None else self.receptor_radius_nm
        if self.sensor != "counted":
            problem = "belongs to sensor 'counted' (sensor 'each_step' reads a fixed share)"
        elif self.receptors is None:
            problem = "belongs to receptors (null: a perfect absorber, whose receptors are all)"
        else:
            s_um, a = self.receptor_radius_nm * 1e-3, self.robot_radius_um
            if self.receptors * s_um * s_um <= 4.0 * a * a:
                return
            most = math.floor(4.0 * a * a / (s_um * s_um))
            problem = (
                f"{self.receptors} receptors of {self.receptor_radius_nm:g} nm do not fit on a "
                f"body of {a:g} um: at most {most} (N s^2 <= 4 a^2)"
            )
        raise field_error("Physics", (field,), value, problem)

    def _time_limit_fits(self) -> Physics:
        """A time limit is at most as many steps of dt_s as learning.max_steps takes: refused
        at dt_s when it was given (it is not the one filled in), else at time_limit_s."""
        limit, dt = self.time_limit_s, self.step_s
        if limit is None or not dt:
            return self
        steps = time_limit_steps(limit, dt)
        if steps <= MAX_STEPS:
            return self
        filled = automatic_dt_s(
            self.diffusion_um2_s or 0.0, self.rotational_diffusion_s or 0.0,
            self.swim_speed_um_s, self.robot_radius_um,
        )  # fmt: skip
        if dt != filled:
            raise field_error(
                "Physics", ("dt_s",), dt,
                f"dt_s {dt:g} s makes time_limit_s {limit:g} s {steps:,} steps, more than the "
                f"{MAX_STEPS:,} learning.max_steps takes: a longer dt_s or a shorter "
                "time_limit_s would do",
            )  # fmt: skip
        raise field_error(
            "Physics", ("time_limit_s",), limit,
            f"{limit:g} s is {steps:,} steps of dt_s {dt:g} s (the largest that resolves the "
            f"motion), more than the {MAX_STEPS:,} learning.max_steps takes: time_limit_s <= "
            f"{rounded_down(MAX_STEPS * dt)} s would do",
        )  # fmt: skip
