"""Results to draw and checks of the PNGs drawn from them."""

import io
from typing import Any

import numpy as np
from matplotlib.figure import Figure
from matplotlib.image import imread
from numpy.typing import NDArray

from nanonav.engine import SimulationResult, Trajectory
from nanonav.scenario import Scenario

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"

# Size in pixels (width, height) of each picture: figure size in inches x figure.DPI.
EXPECTED_SIZE = {
    "heatmap_xy": (640, 620),
    "heatmap_xz": (640, 620),
    "heatmap_yz": (640, 620),
    "heatmap_all": (1520, 540),
    "trajectory": (750, 720),
    "concentration": (800, 600),
    "learning": (900, 600),
    "qtable": (830, 1500),  # it grows with the table: this is 72 states x 4 actions (behaviors)
    "treatment": (900, 700),
}


def scenario(**fields: Any) -> Scenario:
    return Scenario.model_validate(fields)


def decode(png: bytes) -> NDArray[np.float32]:
    assert png.startswith(PNG_SIGNATURE)
    image: NDArray[np.float32] = imread(io.BytesIO(png), format="png")
    return image


def assert_picture(png: bytes, size: tuple[int, int]) -> None:
    image = decode(png)
    height, width = image.shape[:2]
    assert (width, height) == size
    rgb = image[..., :3]
    assert float(rgb.std()) > 0.05
    channels = np.round(rgb * 255).astype(np.uint32)
    packed = (channels[..., 0] << 16) | (channels[..., 1] << 8) | channels[..., 2]
    assert len(np.unique(packed)) > 20


def result_of(trajectory: Trajectory, **fields: Any) -> SimulationResult:
    """A result holding only ``trajectory`` (in a scenario of ``fields``), to draw it."""
    return SimulationResult(
        scenario=scenario(**fields), summary={}, robots=[], episodes=[], work={},
        trajectory=trajectory, qtable=None,
    )  # fmt: skip


def made_trajectory(
    robots: NDArray[np.float64],
    cells: NDArray[np.float64],
    steps: list[int],
    reached: list[bool],
    obstacles: NDArray[np.float64] | None = None,
    radius: float = 1.5,
) -> Trajectory:
    """A trajectory of one row per step from positions ``(rows, n, 3)`` and ``(rows, c, 3)``;
    distances are the true ones, the concentration falls off with them."""
    gaps = np.linalg.norm(robots[:, :, None, :] - cells[:, None, :, :], axis=-1)
    distance = gaps.min(axis=2)
    return Trajectory(
        step=np.arange(robots.shape[0]),
        robots=robots,
        cells=cells,
        obstacles=np.zeros((1, 0, 3)) if obstacles is None else obstacles[None],
        concentration=1.0 / (1.0 + distance),
        distance=distance,
        robot_steps=np.array(steps),
        reached=np.array(reached),
        emitter_offsets=np.zeros((cells.shape[1], 1, 3)),
        obstacle_radius=radius,
    )


def panel_titles(figure: Figure) -> list[str]:
    return [ax.get_title() for ax in figure.axes]
