"""Table 1's rows, as the command line and the dashboard show them: in the active Brownian
physics each length says µm, the concentration nM (to three significant figures, as pM
readings would all print 0.00), and a step how long it lasts."""

from __future__ import annotations

from nanonav import table1

SUMMARY = {
    "total_steps": 1200.0,
    "final_distance": 40.4,
    "average_distance": 71.05,
    "average_concentration": 0.00174,
    "duration_s": 0.03,
    "success_rate": 0.5,
    "collisions": 3.0,
    "path_efficiency": 0.48,
}


def test_physical_rows_carry_their_units() -> None:
    document = {
        "summary": SUMMARY,
        "scenario": {"physics": {"model": "active_brownian", "dt_s": 0.01}},
    }
    shown = {label: value for label, value, _ in table1.rows(document)}
    assert shown["Total Steps (of 0.01 s)"] == "1200.00"
    assert shown["Final Distance"] == "40.40 µm"
    assert shown["Average Distance"] == "71.05 µm"
    assert shown["Average Biomarker Concentration"] == "0.00174 nM"


def test_a_physical_concentration_keeps_its_digits_and_unit_in_the_interval() -> None:
    document = {
        "summary": {**SUMMARY, "average_concentration": 2.3e-05},
        "uncertainty": {"average_concentration": {"ci_low": 1.04e-05, "ci_high": 4.1e-05}},
        "scenario": {"physics": {"model": "active_brownian", "dt_s": 0.01}},
    }
    shown = {label: (value, interval) for label, value, interval in table1.rows(document)}
    assert shown["Average Biomarker Concentration"] == ("2.3e-05 nM", "[1.04e-05 nM, 4.1e-05 nM]")


def test_lattice_rows_are_the_papers_with_their_units() -> None:
    """The lattice's lengths and concentrations had no unit, and its wall-clock time read as
    simulated time ("Simulation Duration per World 2.13e-05 seconds")."""
    document = {"summary": SUMMARY, "scenario": {"physics": {"model": "lattice"}}}
    labels = [label for label, _, _ in table1.rows(document)]
    assert labels[:5] == [
        "Total Steps",
        "Final Distance (length units)",
        "Average Distance (length units)",
        "Average Biomarker Concentration (a.u.)",
        "Computing Time per World",
    ]
    assert [label for label, _, _ in table1.rows({"summary": SUMMARY})] == labels


def test_the_swarms_numbers_follow_table_1_only_when_a_run_has_them() -> None:
    plain = [label for label, _, _ in table1.rows({"summary": SUMMARY})]
    assert "Cells Treated" not in plain and len(plain) == len(table1.METRICS)
    swarm = {**SUMMARY, "cells_treated": 4.5, "treated_fraction": 0.9, "time_to_treat_all": 812.0,
             "robots_per_cell": 3.0, "most_robots_on_a_cell": 3.0, "never_delivered": 0.4,
             "bumps": 12.0}  # fmt: skip
    document = {
        "summary": swarm,
        "uncertainty": {"treated_fraction": {"ci_low": 0.8, "ci_high": 1.0}},
    }
    shown = {label: (value, interval) for label, value, interval in table1.rows(document)}
    assert shown["Share of Cells Treated"] == ("90.0%", "[80.0%, 100.0%]")
    assert shown["Steps to Treat Every Cell"] == ("812.00", "")
    assert list(shown)[len(table1.METRICS)] == "Cells Treated"
