"""A drawn artist's data as the picture tests read it. matplotlib annotates a line's data and a
collection's offsets as anything array-like; a line ``plot`` drew, and a collection, holds an
array (a line ``axhline`` or ``axvline`` drew keeps the list it was given)."""

from __future__ import annotations

from typing import Any

import numpy as np
from matplotlib.collections import Collection
from matplotlib.lines import Line2D
from numpy.typing import NDArray


def xdata(line: Line2D) -> NDArray[Any]:
    """The x values of a line ``plot`` drew."""
    values = line.get_xdata()
    assert isinstance(values, np.ndarray)
    return values


def ydata(line: Line2D) -> NDArray[Any]:
    """The y values of a line ``plot`` drew."""
    values = line.get_ydata()
    assert isinstance(values, np.ndarray)
    return values


def offsets(collection: Collection) -> NDArray[Any]:
    """The points of a collection (a scatter's), a row each."""
    values = collection.get_offsets()
    assert isinstance(values, np.ndarray)
    return values
