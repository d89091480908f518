"""The ``env`` extra's modules, imported by ``nanonav.env`` before anything else of it, so that a
missing one is an error saying which extra to install rather than a bare module name."""

from __future__ import annotations

# The modules the ``env`` extra installs.
EXTRA_MODULES = ("gymnasium", "pettingzoo")


class EnvExtraMissing(ModuleNotFoundError):
    """A module of the ``env`` extra is not installed; the message says how to install it."""


try:
    import gymnasium
    import pettingzoo  # noqa: F401  (the swarm's envs need it: refused here, with the advice)
except ModuleNotFoundError as error:
    if error.name not in EXTRA_MODULES:
        raise
    raise EnvExtraMissing(
        f"nanonav.env needs {error.name}, which is not installed: install the env extra, "
        "pip install -e '.[env]'",
        name=error.name,
    ) from error


def register(env_id: str) -> None:
    """Register the single robot's env and its vector env as ``env_id``, once."""
    if env_id not in gymnasium.registry:
        gymnasium.register(
            id=env_id,
            entry_point="nanonav.env.robot:NanoNavEnv",
            vector_entry_point="nanonav.env.robot:NanoNavVectorEnv",
        )
