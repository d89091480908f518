"""`nanonav --version` says the installed package's version."""

from __future__ import annotations

import importlib.metadata

import pytest

import nanonav
from nanonav.cli import main


def test_version_prints_the_installed_version(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--version"]) == 0
    assert capsys.readouterr().out == f"nanonav {nanonav.__version__}\n"
    assert importlib.metadata.version("nanonav") == nanonav.__version__
