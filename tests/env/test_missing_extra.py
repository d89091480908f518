"""``import nanonav.env`` without the ``env`` extra says which extra to install."""

from __future__ import annotations

import subprocess
import sys

import pytest

from tests.processes import clean_environment

# What the child prints: the error's type, whether it is a ModuleNotFoundError, its module's
# name, then its message.
IMPORT_WITHOUT = """
import sys
sys.modules[{module!r}] = None
try:
    import nanonav.env
except ImportError as error:
    print(type(error).__name__, isinstance(error, ModuleNotFoundError), error.name)
    print(error)
"""


@pytest.mark.parametrize("module", ["gymnasium", "pettingzoo"])
def test_importing_the_envs_without_the_env_extra_says_to_install_it(module: str) -> None:
    done = subprocess.run(
        [sys.executable, "-c", IMPORT_WITHOUT.format(module=module)],
        env=clean_environment(),
        capture_output=True,
        text=True,
        timeout=120,
        check=True,
    )
    kind, message = done.stdout.splitlines()
    assert kind == f"EnvExtraMissing True {module}"
    assert message == (
        f"nanonav.env needs {module}, which is not installed: install the env extra, "
        "pip install -e '.[env]'"
    )
