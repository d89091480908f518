"""The cell list finds exactly the neighbours a brute-force search finds, in O(robots): pairs
against scipy's k-d tree at 10,000 robots, and the first robot a move would run into against a
full scan, also after robots moved within the step and for points outside the grid."""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit
from scipy.spatial import cKDTree

from nanonav.engine import contacts


def cloud(n: int, half: float, seed: int) -> np.ndarray:
    return np.random.default_rng(seed).uniform(-half, half, size=(n, 3))


@pytest.mark.parametrize("cutoff", [0.3, 1.0, 2.5])
def test_pairs_within_a_distance_match_a_k_d_tree_at_ten_thousand_robots(cutoff: float) -> None:
    half = 25.0
    pos = cloud(10_000, half, 1)
    active = np.random.default_rng(2).random(10_000) > 0.1
    grid = contacts.grid_for(half, cutoff, 0.0, len(pos))
    contacts.rebuild(grid, pos, active)
    expected = len(cKDTree(pos[active]).query_pairs(cutoff))
    assert expected > 20  # the check has something to find
    assert contacts.pairs_within(grid, pos, active, cutoff) == expected
    assert grid.dims > 3  # and the grid really splits the space


def brute_first(pos: np.ndarray, active: np.ndarray, point: np.ndarray, distance: float,
                skip: int) -> int:  # fmt: skip
    close = np.flatnonzero(active & (np.sum((pos - point) ** 2, axis=1) < distance**2))
    close = close[close != skip]
    return int(close.min()) if len(close) else -1


def test_the_first_robot_a_move_runs_into_is_found_after_moves_within_the_step() -> None:
    half, radius, step = 20.0, 0.5, 0.4
    rng = np.random.default_rng(3)
    pos = cloud(3_000, half, 4)
    active = np.ones(len(pos), dtype=np.bool_)
    active[::7] = False
    grid = contacts.grid_for(half, 2 * radius, step, len(pos))
    contacts.rebuild(grid, pos, active)
    # every robot moves up to a step, the grid still lists it where it was
    shift = rng.normal(size=pos.shape)
    shift *= (step * rng.random(len(pos)) / np.linalg.norm(shift, axis=1))[:, None]
    moved = pos + shift
    hits = 0
    for i in range(0, len(pos), 3):
        point = moved[i] + rng.uniform(-0.3, 0.3, size=3)
        px, py, pz = point
        got = contacts.first_within(grid, moved, active, px, py, pz, 2 * radius, i)
        assert got == brute_first(moved, active, point, 2 * radius, i), i
        hits += got >= 0
    assert hits > 50


def test_points_outside_the_grid_are_still_found() -> None:
    # a space without walls: robots drift out of the cube the grid covers
    pos = np.array([[30.0, 0.0, 0.0], [30.5, 0.2, 0.0], [-40.0, -40.0, 39.0], [-40.3, -40.0, 39.0]])
    active = np.ones(4, dtype=np.bool_)
    grid = contacts.grid_for(10.0, 1.0, 0.0, 4)
    contacts.rebuild(grid, pos, active)
    assert contacts.pairs_within(grid, pos, active, 1.0) == 2
    assert contacts.first_within(grid, pos, active, 30.2, 0.0, 0.0, 1.0, 0) == 1
    assert contacts.first_within(grid, pos, active, 0.0, 0.0, 0.0, 1.0, -1) == -1


def test_the_grid_is_sized_by_the_cutoff_and_its_memory_by_the_robots() -> None:
    grid = contacts.grid_for(10.0, 1.0, 1.0, 5000)
    assert grid.width >= 2.0 and grid.dims == 10 and grid.slack == 1.0
    assert grid.heads.shape[0] == 10**3  # fewer cells than buckets: each cell its own
    fine = contacts.grid_for(1000.0, 0.001, 0.0, 1000)
    assert fine.width >= 0.002
    # two million cells a side would not fit: they share a bucket or two per robot
    assert fine.heads.shape[0] == 2048  # two a robot, rounded up to a power of two
    for bad in ((0.0, 1.0, 0.0), (1.0, -1.0, 0.0), (1.0, 1.0, -0.5)):
        with pytest.raises(ValueError):
            contacts.grid_for(*bad, 5)


def test_relisting_as_robots_move_keeps_every_search_exact_however_far_they_go() -> None:
    rng = np.random.default_rng(7)
    pos = rng.uniform(-20.0, 20.0, (2_000, 3))
    everyone = np.ones(len(pos), dtype=np.bool_)
    grid = contacts.grid_for(20.0, 1.0, 0.0, len(pos))  # cells as wide as the cutoff only
    contacts.rebuild(grid, pos, everyone)
    for i in rng.integers(0, len(pos), 3_000):
        pos[i] += rng.normal(0.0, 5.0, 3)  # jumps of many cells, and out of the grid
        contacts.relist(grid, int(i), *pos[i])
    assert sorted(np.flatnonzero(grid.cell >= 0)) == list(range(len(pos)))  # each listed once
    tree = cKDTree(pos)
    for point in rng.uniform(-25.0, 25.0, (200, 3)):
        found = np.empty(len(pos), dtype=np.int64)
        px, py, pz = point
        k = contacts.each_within(grid, pos, px, py, pz, 1.0, found)
        expected = sorted(j for j in tree.query_ball_point(point, 1.0 - 1e-12))
        assert found[:k].tolist() == expected
        nearest = contacts.first_within(grid, pos, everyone, px, py, pz, 1.0, -1)
        assert nearest == (expected[0] if expected else -1)


def test_a_hashed_grid_finds_what_a_k_d_tree_finds_when_far_cells_share_buckets() -> None:
    # cells of 0.4 in a 100-unit cube, 500 robots: 16 million cells in 1,000 buckets
    pos = cloud(500, 50.0, 11)
    pos[:100] = pos[0] + np.random.default_rng(3).normal(0.0, 0.3, (100, 3))  # a tight cluster
    grid = contacts.grid_for(50.0, 0.2, 0.0, len(pos))
    active = np.ones(len(pos), dtype=np.bool_)
    contacts.rebuild(grid, pos, active)
    assert contacts.pairs_within(grid, pos, active, 0.2) == len(cKDTree(pos).query_pairs(0.2))
    found = np.empty(len(pos), dtype=np.int64)
    for point in pos[:50]:
        px, py, pz = point
        k = contacts.each_within(grid, pos, px, py, pz, 0.2, found)
        assert found[:k].tolist() == sorted(cKDTree(pos).query_ball_point(point, 0.2 - 1e-12))


@njit()
def _pushed_out(c: np.ndarray, reach: float, point: np.ndarray) -> tuple[float, float, float, bool]:
    return contacts.pushed_out(c[0], c[1], c[2], reach, point[0], point[1], point[2])


def test_a_point_inside_a_body_is_pushed_out_along_the_line_of_centres_to_contact() -> None:
    centre = np.array([1.0, -2.0, 0.5])
    x, y, z, inside = _pushed_out(centre, 3.0, centre + np.array([0.6, 0.8, 0.0]))
    assert inside
    assert np.hypot(x - 1.0, y + 2.0) == pytest.approx(3.0, rel=1e-9)
    assert (x - 1.0) / (y + 2.0) == pytest.approx(0.6 / 0.8)
    assert z == pytest.approx(0.5)
    # a point already clear, or the very centre, is not a contact: it is left where it is
    assert _pushed_out(centre, 3.0, centre + 3.5)[3] is False
    assert _pushed_out(centre, 3.0, centre)[3] is False


@njit()
def _time_to_slide(reach: float, speed: float, impact: float, dt: float, to_angle: float) -> float:
    # a swimmer headed along +x meets a fixed sphere at the given impact parameter and is
    # pushed out after each step; the time until its polar angle from -x reaches ``to_angle``
    x = -np.sqrt(reach * reach - impact * impact) * (1.0 + 1e-12)
    y = impact
    t = 0.0
    while np.arctan2(y, -x) < to_angle:
        nx, ny, _, _ = contacts.pushed_out(0.0, 0.0, 0.0, reach, x + speed * dt, y, 0.0)
        x = nx
        y = ny
        t += dt
    return t


@pytest.mark.parametrize("dt", [0.01, 0.0025])
def test_a_swimmer_pushed_against_a_sphere_slides_round_it_as_a_hard_sphere_does(dt: float) -> None:
    # On the surface only the tangential part of the swim survives: d(alpha)/dt = v sin(alpha)
    # / R, alpha measured from the head-on point, so from alpha0 to alpha1 it takes
    # (R / v) [ln tan(a / 2)] between them, whatever the step (a move refused whole would never
    # get there: every step points into the sphere).
    reach, speed, impact, to_angle = 10.0, 5.0, 5.0, np.radians(80.0)
    a0 = np.arcsin(impact / reach)

    def f(a: float) -> float:
        return float(np.log(np.tan(a / 2)))

    expected = reach / speed * (f(to_angle) - f(a0))
    assert _time_to_slide(reach, speed, impact, dt, to_angle) == pytest.approx(expected, rel=0.01)
