"""The site's reference pages are generated from the code, and a stale one fails here."""

from __future__ import annotations

import importlib.util
import re
import sys
from pathlib import Path
from types import ModuleType

import pytest

from nanonav.scenario import PRESETS, Scenario
from nanonav.settings import Settings
from tests.conftest import Api

ROOT = Path(__file__).resolve().parents[2]


def load_reference() -> ModuleType:
    spec = importlib.util.spec_from_file_location("reference", ROOT / "docs/_scripts/reference.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules.setdefault("reference", module)
    spec.loader.exec_module(module)
    return module


reference = load_reference()


@pytest.fixture(scope="module")
def pages() -> dict[str, str]:
    return dict(reference.pages())


def leaf_fields(model: type[object], prefix: str = "") -> list[str]:
    names = []
    for name, field in model.model_fields.items():  # type: ignore[attr-defined]
        kind = field.annotation
        if isinstance(kind, type) and hasattr(kind, "model_fields"):
            names += leaf_fields(kind, f"{prefix}{name}.")
        else:
            names.append(f"{prefix}{name}")
    return names


def test_no_reference_page_is_stale() -> None:
    assert reference.stale() == [], "docs/reference is stale: run `make docs` and commit it"


def test_a_changed_page_is_found_stale(tmp_path: Path) -> None:
    reference.write(tmp_path)
    assert reference.stale(tmp_path) == []
    (tmp_path / "settings.md").write_text("# Settings\n")
    (tmp_path / "cli.md").unlink()
    assert sorted(reference.stale(tmp_path)) == ["cli.md", "settings.md"]


def test_every_scenario_field_is_a_row_with_its_default(pages: dict[str, str]) -> None:
    page = pages["scenario.md"]
    fields = leaf_fields(Scenario)
    assert len(fields) > 70
    for name in fields:
        assert f"| `{name}`<br>type: " in page, name
    row = next(line for line in page.splitlines() if line.startswith("| `learning.gamma`<br>"))
    assert f"default: `{Scenario().learning.gamma}`" in row and "bounds: ≥ 0" in row
    radius = next(line for line in page.splitlines() if line.startswith("| `physics.robot_radius"))
    assert "<br>unit: µm |" in radius


def test_every_preset_has_a_section_with_what_it_changes(pages: dict[str, str]) -> None:
    page = pages["presets.md"]
    for name in PRESETS:
        assert f"## `{name}`" in page
    swarm = page.split("## `paper-swarm`")[1].split("## ")[0]
    assert "| `robots.count` | `15` | `1` |" in swarm


def test_every_setting_is_named_by_its_variable(pages: dict[str, str]) -> None:
    page = pages["settings.md"]
    for name, field in Settings.model_fields.items():
        assert f"`NANONAV_{name.upper()}`" in page
        assert (field.description or "x")[:30] in page
    assert "`DATABASE_URL`" in page


def test_every_route_and_command_is_listed(pages: dict[str, str]) -> None:
    routes = pages["routes.md"]
    for path in ("`/jobs`", "`/jobs/{job_id}/plots/{name}.png`", "`/policies`", "`/ui/jobs`"):
        assert path in routes
    commands = pages["cli.md"]
    for command in ("run", "api", "worker", "submit", "study", "policy", "train"):
        assert f"## `nanonav {command}`" in commands


def test_every_path_the_routes_page_names_is_served(pages: dict[str, str], api: Api) -> None:
    """The page's prose names no route the service does not have (it named /readyz, which
    answered 404): each, its parameters filled, is answered by a route, not the router's 404."""
    named = set(re.findall(r"`(/[^`\s?]*)`", pages["routes.md"]))
    assert len(named) > 30
    missing = api.client.get("/no-such-route").content.replace(b"/no-such-route", b"")
    unserved = []
    for path in sorted(named):
        filled = re.sub(r"\{[^}]*\}", "1", path)
        answer = api.client.get(filled)
        if answer.status_code == 404 and answer.content.replace(filled.encode(), b"") == missing:
            unserved.append(path)
    assert unserved == []


@pytest.mark.parametrize(
    ("name", "unit"),
    [
        ("robot_radius_um", "µm"),
        ("swim_speed_um_s", "µm/s"),
        ("diffusion_um2_s", "µm²/s"),
        ("dt_s", "s"),
        ("decay_rate_s", "1/s"),
        ("tumble_rate_rising_s", "1/s"),
        ("rotational_diffusion_s", "rad²/s"),
        ("temperature_k", "K"),
        ("size", ""),
    ],
)
def test_a_unit_is_read_off_the_name(name: str, unit: str) -> None:
    assert reference.unit_of(name) == unit
