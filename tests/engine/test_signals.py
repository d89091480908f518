"""The chemical-signal grid against theory: trilinear reading is exact for a linear field, a
release deposits exactly its amount where it was made, reflecting faces conserve the mass but for
decay, an impulse spreads as the free-space Green's function with FTCS's exact second moment, a
constant source settles to the screened steady state, absorbing faces leak, and the step bound
keeps every node non-negative while a step past it blows up."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.typing import NDArray

from nanonav.engine import signals
from nanonav.engine.signals import SignalGrid

Point = tuple[float, float, float] | NDArray[np.float64]


def axis(grid: SignalGrid) -> NDArray[np.float64]:
    return np.asarray(grid.origin + grid.spacing * np.arange(grid.dims), dtype=np.float64)


def squared_distance(grid: SignalGrid, point: tuple[float, float, float]) -> NDArray[np.float64]:
    x = axis(grid)
    return ((x - point[0])[:, None, None] ** 2 + (x - point[1])[None, :, None] ** 2
            + (x - point[2])[None, None, :] ** 2)  # fmt: skip


def put(grid: SignalGrid, point: Point, amount: float, species: int = 0) -> None:
    x, y, z = (float(v) for v in point)
    signals.release(grid.conc, grid.origin, grid.spacing, grid.dims, species, x, y, z, amount)


def step(grid: SignalGrid, diffusion: float, decay: float, dt: float, no_flux: bool,
         species: int = 0) -> None:  # fmt: skip
    signals.diffuse(grid.conc, grid.scratch, grid.spacing, grid.dims, species, diffusion, decay,
                    dt, no_flux)  # fmt: skip


def read(grid: SignalGrid, point: Point, species: int = 0) -> tuple[float, float, float, float]:
    x, y, z = (float(v) for v in point)
    c, dx, dy, dz = signals.sample(
        grid.conc, grid.origin, grid.spacing, grid.dims, species, x, y, z
    )
    return float(c), float(dx), float(dy), float(dz)


def mass(grid: SignalGrid, species: int = 0) -> float:
    return float(signals.total(grid.conc, grid.spacing, species))


def test_the_grid_spans_the_cube_with_nodes_on_both_faces() -> None:
    grid = signals.grid_for(3.0, 13, 2)
    assert grid.conc.shape == (2, 13, 13, 13) and grid.scratch.shape == (13, 13, 13)
    assert grid.spacing == 0.5 and grid.origin == -3.0 and axis(grid)[-1] == 3.0
    assert not grid.conc.any()
    for bad in ((0.0, 13, 1), (3.0, 1, 1), (3.0, 13, 0)):
        with pytest.raises(ValueError):
            signals.grid_for(*bad)


def test_trilinear_reading_reproduces_a_linear_field_and_its_gradient() -> None:
    grid = signals.grid_for(3.0, 13, 2)
    a, b = 7.0, np.array([1.5, -0.75, 2.25])
    x = axis(grid)
    grid.conc[1] = a + b[0] * x[:, None, None] + b[1] * x[None, :, None] + b[2] * x[None, None, :]
    rng = np.random.default_rng(5)
    # The interpolant of a linear field is the field itself, so only round-off is left: |c| < 30
    # and a few operations of eps 2e-16 each, far below 1e-12.
    for point in rng.uniform(-3.0, 3.0, (300, 3)):
        c, *grad = read(grid, point, species=1)
        assert c == pytest.approx(a + b @ point, abs=1e-12)
        assert grad == pytest.approx(b, abs=1e-12)
        assert read(grid, point, species=0) == (0.0, 0.0, 0.0, 0.0)  # species apart
    # Outside, the point is clamped onto the boundary: the value there, the same gradient.
    for point in rng.uniform(-9.0, 9.0, (100, 3)):
        c, *grad = read(grid, point, species=1)
        assert c == pytest.approx(a + b @ np.clip(point, -3.0, 3.0), abs=1e-12)
        assert grad == pytest.approx(b, abs=1e-12)


def test_a_release_deposits_exactly_its_amount_centred_on_the_point() -> None:
    grid = signals.grid_for(3.0, 13, 1)  # spacing 0.5: the h^3 matters
    rng = np.random.default_rng(6)
    x = axis(grid)
    outside = [[3.0, -3.0, 0.25], [7.0, -0.1, -5.0]]  # on a face, beyond two
    points = np.vstack([rng.uniform(-3.0, 3.0, (20, 3)), outside])
    for point in points:
        grid.conc[:] = 0.0
        put(grid, point, 2.5)
        c = grid.conc[0]
        # Weights summing to 1, so round-off only: a few eps of 2.5.
        assert mass(grid) == pytest.approx(2.5, rel=1e-14)
        assert np.count_nonzero(c) <= 8 and c.min() >= 0.0
        moments = [np.sum(c * x[:, None, None]), np.sum(c * x[None, :, None]),
                   np.sum(c * x[None, None, :])]  # fmt: skip
        centre = np.array(moments) * grid.spacing**3 / 2.5
        # The centre of mass is the point (clamped onto the grid), to round-off on coordinates < 3.
        assert centre == pytest.approx(np.clip(point, -3.0, 3.0), abs=1e-13)


def test_reflecting_faces_conserve_the_mass_but_for_decay() -> None:
    grid = signals.grid_for(4.0, 17, 1)
    diffusion, decay = 0.3, 0.02
    dt = signals.stable_step(diffusion, decay, grid.spacing)
    put(grid, (-3.8, 3.7, -3.9), 1.0)  # by a corner, so the faces are reached at once
    put(grid, (0.3, 0.1, -0.2), 2.0)
    steps = 300
    for _ in range(steps):
        step(grid, diffusion, decay, dt, True)
    got = mass(grid)
    # FTCS with mirrored ghosts conserves sum c h^3 exactly, decay takes (1 - k dt) a step, so
    # only round-off is left: about eps per node and step, relatively, far below 1e-11.
    assert got == pytest.approx(3.0 * (1.0 - decay * dt) ** steps, rel=1e-11)
    # Against the continuous exp(-k t): n log(1 - k dt) = -k t - n (k dt)^2 / 2 - ..., so the
    # relative difference is about n (k dt)^2 / 2; here about 1e-3, bounded by twice that.
    t = steps * dt
    assert abs(got / (3.0 * math.exp(-decay * t)) - 1.0) <= steps * (decay * dt) ** 2
    assert decay * t > 0.5  # it did decay
    assert grid.conc[0, -1, 0, -1] > 0.3 * grid.conc[0].mean()  # and the far faces were reached


def test_an_impulse_spreads_as_the_free_space_greens_function() -> None:
    grid = signals.grid_for(30.0, 61, 1)  # h = 1
    diffusion, decay, amount = 1.0, 0.02, 3.0
    # Half the bound: at the bound itself the impulse would hop between the two halves of the
    # lattice (see the checkerboard test below), half of it damps that mode at once.
    dt = 0.5 * signals.stable_step(diffusion, decay, grid.spacing)
    steps = 240
    put(grid, (0.0, 0.0, 0.0), amount)
    for _ in range(steps):
        step(grid, diffusion, decay, dt, False)
    t = steps * dt
    spread = diffusion * t  # D t = 20, so 4 D t = 80 h^2 and h^2 / (D t) = 0.05
    r2 = squared_distance(grid, (0.0, 0.0, 0.0))
    c = grid.conc[0]
    green = amount * (4 * math.pi * spread) ** -1.5 * np.exp(-r2 / (4 * spread) - decay * t)
    # The lattice walk's fourth cumulants make the leading error, relative (h^2 / D t) P(rho),
    # rho = r^2 / 4 D t, P a quadratic in rho (Edgeworth); P(0) = 1/32 at this step. Measured
    # P up to 0.03 + 0.03 rho^2; bounded by 0.05 + 0.04 rho^2: 0.25 % at the centre, 2.1 % at
    # rho = 3 (where the field is e^-3 of its peak). The decay's (1 - k dt)^n against exp(-k t)
    # is 3e-4 more.
    rho = r2 / (4 * spread)
    near = rho <= 3.0
    assert np.count_nonzero(near) > 10_000
    error = np.abs(c[near] / green[near] - 1.0)
    assert np.all(error <= grid.spacing**2 / spread * (0.05 + 0.04 * rho[near] ** 2))
    # Second moment: FTCS's walk adds 6 r h^2 / (1 - k dt) = 6 D dt / (1 - k dt) of variance a
    # step, exactly on an infinite lattice; the faces, 4.7 sigma away, cost < 1e-4.
    total = np.sum(c) * grid.spacing**3
    second = np.sum(c * r2) * grid.spacing**3 / total
    assert second == pytest.approx(6 * spread / (1.0 - decay * dt), rel=1e-4)
    assert second == pytest.approx(6 * spread, rel=decay * dt + 1e-4)  # 6 D t as k dt -> 0
    assert total == pytest.approx(amount * (1.0 - decay * dt) ** steps, rel=1e-4)  # barely leaks


def test_at_the_bound_an_impulse_hops_between_the_two_halves_of_the_lattice() -> None:
    # Why the Green's function test takes half the bound: without decay the node's own weight is
    # 0 at the bound (a float above, see stable_step), so after an even number of steps the odd
    # nodes hold nothing but round-off.
    grid = signals.grid_for(10.0, 21, 1)
    put(grid, (0.0, 0.0, 0.0), 1.0)
    dt = signals.stable_step(1.0, 0.0, grid.spacing)
    for _ in range(8):  # the faces, 10 steps away, would mix the halves
        step(grid, 1.0, 0.0, dt, True)
    i = np.arange(21)
    odd = (i[:, None, None] + i[None, :, None] + i[None, None, :]) % 2 == 1
    assert grid.conc[0][odd].max() < 1e-14 * grid.conc[0][~odd].max()
    step(grid, 1.0, 0.0, 0.5 * dt, True)  # half the bound fills both halves in one step
    assert grid.conc[0][odd].sum() > 0.4 * grid.conc[0].sum()


def test_a_constant_source_settles_to_the_screened_steady_state() -> None:
    grid = signals.grid_for(30.0, 61, 1)  # h = 1, the faces 5 lambda from the source
    diffusion, length = 1.0, 6.0
    decay = diffusion / length**2
    rate = 2.0
    # The steady state of the scheme solves D lap_h c - k c = -q delta / h^3 whatever the step,
    # so the bound itself is fine here.
    dt = signals.stable_step(diffusion, decay, grid.spacing)
    steps = round(8.0 / (decay * dt))  # k t = 8: what is still to come is < 1e-3 within 3 lambda
    for _ in range(steps):
        put(grid, (0.0, 0.0, 0.0), rate * dt)
        step(grid, diffusion, decay, dt, True)
    put(grid, (0.0, 0.0, 0.0), rate * dt)
    r = np.sqrt(squared_distance(grid, (0.0, 0.0, 0.0)))
    shell = (r >= 3.0 * grid.spacing) & (r <= 3.0 * length)
    expected = rate * np.exp(-r[shell] / length) / (4 * math.pi * diffusion * r[shell])
    error = np.abs(grid.conc[0][shell] / expected - 1.0)
    # The 7-point lattice's Green's function differs from the continuum's by relative O(h^2/r^2),
    # anisotropically (above it along the axes, below along the diagonals), and its screening by
    # O(h^2/lambda^2). Measured: 5.9 % at r = 3 h on an axis, 3.5 % at 4 h, 0.8 % at 12 h;
    # bounded by 0.6 (h/r)^2 + 0.5 (h/lambda)^2, 8 % at 3 h, 5 % at 4 h, under 2 % beyond 10 h.
    # The reflecting faces' images, 5 lambda out, add up to 0.7 % (at 3 lambda towards a face).
    h = grid.spacing
    assert np.all(error <= 0.6 * (h / r[shell]) ** 2 + 0.5 * (h / length) ** 2)
    assert np.count_nonzero(shell) > 10_000


def test_absorbing_faces_leak_and_stay_non_negative() -> None:
    reflecting = signals.grid_for(4.0, 17, 1)
    absorbing = signals.grid_for(4.0, 17, 1)
    diffusion, decay = 0.3, 0.05
    dt = signals.stable_step(diffusion, decay, reflecting.spacing)
    for grid in (reflecting, absorbing):
        put(grid, (2.9, -0.4, 0.8), 1.0)  # a few spacings from a face
    before = mass(absorbing)
    for _ in range(100):
        step(reflecting, diffusion, decay, dt, True)
        step(absorbing, diffusion, decay, dt, False)
        now = mass(absorbing)
        # never more than decay alone leaves, but for round-off before the field reaches a face
        assert now <= before * (1.0 - decay * dt) * (1.0 + 1e-14)
        before = now
        assert absorbing.conc.min() >= 0.0 and reflecting.conc.min() >= 0.0
    assert mass(absorbing) < 0.9 * mass(reflecting)


@pytest.mark.parametrize("no_flux", [True, False])
def test_the_step_bound_keeps_nodes_non_negative_and_a_step_past_it_blows_up(no_flux: bool) -> None:
    rng = np.random.default_rng(8)
    # exactly non-negative at the bound, whatever rounding does to the node's own weight
    for diffusion, decay, spacing in [(1.0, 0.0, 1.0), (0.0, 0.3, 1.0),
                                      *rng.uniform(0.01, 3.0, (20, 3))]:  # fmt: skip
        dt = signals.stable_step(diffusion, decay, spacing)
        assert dt * (6 * diffusion / spacing**2 + decay) <= 1.0 + 1e-15
        assert dt * (6 * diffusion / spacing**2 + decay) >= 1.0 - 1e-15  # the largest
        grid = signals.grid_for(3.0, 7, 1)
        grid = grid._replace(spacing=spacing)
        put(grid, (0.0, 0.0, 0.0), 1.0)
        step(grid, diffusion, decay, dt, no_flux)
        assert grid.conc.min() >= 0.0
    # A field of random non-negative values and an impulse: non-negative at the bound, and the
    # maximum never grows (each node a mix of itself and its neighbours with weights summing to
    # 1 - k dt).
    diffusion, decay = 0.5, 0.3
    grid = signals.grid_for(4.0, 17, 1)
    grid.conc[0] = rng.random((17, 17, 17))
    put(grid, (0.1, 0.2, -0.3), 5.0)
    start = grid.conc.copy()
    dt = signals.stable_step(diffusion, decay, grid.spacing)
    top = grid.conc.max()
    for _ in range(50):
        step(grid, diffusion, decay, dt, no_flux)
        assert grid.conc.min() >= 0.0 and grid.conc.max() <= top
        top = grid.conc.max()
    # 2.5 times the bound is past the stability limit dt (12 D / h^2 + k) <= 2 too: the
    # checkerboard mode grows by |1 - 12 r - k dt| ~ 4 a step.
    grid.conc[:] = start
    step(grid, diffusion, decay, 2.5 * dt, no_flux)
    assert grid.conc.min() < 0.0
    for _ in range(30):
        step(grid, diffusion, decay, 2.5 * dt, no_flux)
    assert np.abs(grid.conc).max() > 1e6 * start.max()


def test_an_empty_species_is_told_apart_and_stays_empty() -> None:
    grid = signals.grid_for(2.0, 9, 2)
    assert signals.is_zero(grid.conc, 0) and signals.is_zero(grid.conc, 1)
    step(grid, 1.0, 0.1, signals.stable_step(1.0, 0.1, grid.spacing), False, species=1)
    assert signals.is_zero(grid.conc, 1)
    put(grid, (1.9, 1.9, 1.9), 1e-30, species=1)
    assert signals.is_zero(grid.conc, 0) and not signals.is_zero(grid.conc, 1)
