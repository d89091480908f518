"""The swarm's treatment picture: cells treated over the steps and each cell's payloads, drawn
only for a run that reports the swarm's numbers."""

from dataclasses import replace

import numpy as np
import pytest
from matplotlib.collections import PolyCollection

from nanonav.engine import SimulationResult
from nanonav.pictures.job import PICTURE_NAMES, render, render_all, treatment_drawn
from nanonav.pictures.job.treatment import (
    MAX_CELL_LINES,
    delivers_payloads,
    has_treatment,
    treated_counts,
    treatment_figure,
    treatment_png,
)
from nanonav.scenario import Scenario, preset_scenario
from tests.pictures.data import ydata
from tests.pictures.job.results import (
    EXPECTED_SIZE,
    assert_picture,
    decode,
    made_trajectory,
    result_of,
)
from tests.pictures.job.swarm import treating_run, untreated_run


@pytest.fixture(scope="module")
def treating() -> SimulationResult:
    return treating_run()


@pytest.fixture(scope="module")
def untreated() -> SimulationResult:
    return untreated_run()


def test_the_picture_shows_cells_being_treated_and_differs_from_one_where_none_is(
    treating: SimulationResult, untreated: SimulationResult
) -> None:
    assert treating.summary["cells_treated"] == 3 and untreated.summary["cells_treated"] == 0
    drawn = {}
    for name, result in (("treating", treating), ("untreated", untreated)):
        png = treatment_png(result)
        assert_picture(png, EXPECTED_SIZE["treatment"])
        drawn[name] = decode(png)
    assert np.abs(drawn["treating"] - drawn["untreated"]).max() > 0.5
    figure = treatment_figure(treating)
    counts_ax, loads_ax = figure.axes
    assert counts_ax.get_ylabel() == "cells treated" and loads_ax.get_ylabel() == "payloads"
    assert loads_ax.get_xlabel() == "step"
    treated = np.asarray(counts_ax.get_lines()[0].get_ydata())
    assert treated[0] == 0 and treated[-1] == 3
    ceiling = [line for line in counts_ax.get_lines() if line.get_linestyle() == "--"]
    assert [np.asarray(line.get_ydata())[0] for line in ceiling] == [3]  # a line at every cell
    finished = int(treating.summary["time_to_treat_all"])
    assert f"every cell treated at step {finished}" in figure.get_suptitle()


def test_cells_count_as_treated_once_their_load_reaches_the_capacity() -> None:
    loads = np.array([[0, 0, 0], [1, 0, 2], [3, 1, 2], [3, 3, 4]])
    assert treated_counts(loads, 3).tolist() == [0, 0, 1, 3]
    assert treated_counts(loads, None).tolist() == [0, 2, 3, 3]  # no capacity: cells reached


def loaded(cells: int, capacity: int | None) -> SimulationResult:
    """A made-up episode of ``cells`` cells filling up one payload per cell every two steps."""
    rows = 7
    positions = np.zeros((rows, cells, 3))
    positions[:, :, 0] = np.linspace(-20, 20, cells)
    trajectory = made_trajectory(
        np.zeros((rows, 1, 3)), positions, steps=[rows - 1], reached=[False]
    )
    loads = np.minimum(np.arange(rows)[:, None] // 2 + np.arange(cells)[None, :] % 2, 3)
    return replace(
        result_of(
            replace(trajectory, cell_loads=loads, delivered_to=np.array([-1])),
            robots={"count": 1, "exclusion": True},
            cells={"count": cells, "capacity": capacity},
            # without a capacity, robots that signal once bound still deliver payloads
            communication={"model": "none" if capacity is not None else "attractant"},
        ),
        summary={"robots_per_cell": 1.0, "most_robots_on_a_cell": 3, "bumps": 0},
    )


def test_a_few_cells_get_a_line_each_and_many_are_stacked() -> None:
    few = treatment_figure(loaded(MAX_CELL_LINES, 3)).axes[1]
    cells = [line for line in few.get_lines() if str(line.get_label()).startswith("_child")]
    assert len(cells) >= MAX_CELL_LINES
    assert not [c for c in few.collections if isinstance(c, PolyCollection)]
    many = treatment_figure(loaded(MAX_CELL_LINES + 4, 3)).axes[1]
    bands = [c for c in many.collections if isinstance(c, PolyCollection)]
    assert len(bands) == MAX_CELL_LINES + 4
    assert "stacked" in many.get_title()
    assert_picture(treatment_png(loaded(MAX_CELL_LINES + 4, None)), EXPECTED_SIZE["treatment"])


def test_each_cells_line_is_at_its_exact_load_and_never_over_the_capacity() -> None:
    """Lines nudged apart read 3.13 payloads over the capacity line at 3: each is drawn at its
    load, those of the same load nested, thinner over wider."""
    result = loaded(MAX_CELL_LINES, 3)
    axes = treatment_figure(result).axes[1]
    assert result.trajectory is not None and result.trajectory.cell_loads is not None
    lines = [line for line in axes.get_lines() if str(line.get_label()).startswith("_child")]
    cells = [line for line in lines if line.get_linestyle() == "-"]
    assert len(cells) == MAX_CELL_LINES
    for j, line in enumerate(cells):
        assert np.array_equal(line.get_ydata(), result.trajectory.cell_loads[:, j])
        assert max(ydata(line)) <= 3
    widths = [line.get_linewidth() for line in cells]
    assert widths == sorted(widths, reverse=True) and widths[-1] >= 1.2


def test_without_a_capacity_the_picture_counts_the_cells_that_received_a_payload() -> None:
    figure = treatment_figure(loaded(3, None))
    assert figure.axes[0].get_ylabel() == "cells with a payload"
    assert "none is ever treated" in figure.axes[0].get_title()


def test_only_a_result_with_the_swarms_numbers_has_the_picture(
    swarm: SimulationResult, treating: SimulationResult
) -> None:
    assert "treatment" in PICTURE_NAMES
    assert not has_treatment(swarm)  # the paper's swarm records cell loads, but is no such run
    assert "treatment" not in render_all(swarm)
    with pytest.raises(ValueError, match="no treatment to draw"):
        render(swarm, "treatment")
    pictures = render_all(treating)
    assert_picture(pictures["treatment"], EXPECTED_SIZE["treatment"])
    assert pictures["treatment"] == render(treating, "treatment")


def test_a_stored_result_draws_the_same_treatment_and_an_older_one_none(
    treating: SimulationResult,
) -> None:
    arrays = treating.arrays()
    stored = SimulationResult.from_stored(treating.to_dict(), arrays)
    assert treatment_png(stored) == treatment_png(treating)
    older = {k: v for k, v in arrays.items() if k not in ("cell_loads", "delivered_to", "signals")}
    assert not has_treatment(SimulationResult.from_stored(treating.to_dict(), older))


@pytest.mark.parametrize(
    ("overrides", "delivers"),
    [
        ({}, False),
        ({"robots": {"exclusion": True}}, False),  # the swarm's numbers, but no payload
        ({"cells": {"capacity": 2}}, True),
        ({"communication": {"model": "broadcast"}, "robots": {"policy": "rule"}}, True),
    ],
)
def test_the_service_knows_from_the_scenario_alone_which_jobs_have_it(
    overrides: dict[str, object], delivers: bool
) -> None:
    scenario = Scenario.model_validate(overrides)
    assert treatment_drawn(scenario.model_dump(mode="json")) is delivers
    assert delivers_payloads(scenario) is delivers
    assert treatment_drawn(preset_scenario("diffuse-tumour").model_dump(mode="json"))
