"""A package's public names imported when first asked for (PEP 562), so that importing the
package, or a light module of it, does not load its heavy ones (numba, matplotlib)."""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from typing import Any


def names_from(
    package: str, homes: Mapping[str, str], namespace: dict[str, Any]
) -> Callable[[str], Any]:
    """The package's ``__getattr__``: a name of ``homes`` imported from its module of
    ``package`` (``homes[name]``) the first time it is asked for, then kept in ``namespace``
    (the package's globals) so it is not asked for again."""

    def __getattr__(name: str) -> Any:
        home = homes.get(name)
        if home is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(f"{package}.{home}"), name)
        namespace[name] = value
        return value

    return __getattr__
