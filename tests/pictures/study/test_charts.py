"""Study pictures: every PNG decodes at its promised size, shows each series in its colour, and
says so when there is nothing to draw."""

import io

import numpy as np
import pytest
from matplotlib.colors import to_rgb
from matplotlib.image import imread
from numpy.typing import NDArray

from nanonav.pictures.figure import png
from nanonav.pictures.study import charts
from nanonav.pictures.study.charts import SERIES_COLOURS, Series, learning_png, metric_png
from tests.pictures.data import offsets

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
METRIC_SIZE = (800, 500)  # 8 x 5 inches at 100 DPI
BLUE, ORANGE, GREEN = SERIES_COLOURS[:3]


def decode(png: bytes) -> NDArray[np.uint8]:
    """The picture as 0-255 RGB."""
    assert png.startswith(PNG_SIGNATURE)
    image: NDArray[np.float32] = imread(io.BytesIO(png), format="png")
    return np.round(image[..., :3] * 255).astype(np.uint8)


def size(image: NDArray[np.uint8]) -> tuple[int, int]:
    return image.shape[1], image.shape[0]


def distinct_colours(image: NDArray[np.uint8]) -> int:
    packed = image.astype(np.uint32)
    return len(np.unique((packed[..., 0] << 16) | (packed[..., 1] << 8) | packed[..., 2]))


def pixels_of(image: NDArray[np.uint8], colour: str, alpha: float = 1.0) -> int:
    """Pixels of ``colour`` (drawn with ``alpha`` over white), to within antialiasing noise."""
    target = 255 * (alpha * np.array(to_rgb(colour)) + (1 - alpha))
    return int(np.all(np.abs(image.astype(float) - target) <= 3, axis=-1).sum())


def tinted(image: NDArray[np.uint8], colour: str) -> int:
    """Pixels at least half ``colour`` over white: thin antialiased lines included."""
    white = np.full(3, 255.0)
    direction = white - 255 * np.array(to_rgb(colour))
    away = white - image.astype(float)
    alpha = away @ direction / (direction @ direction)
    residual = np.linalg.norm(away - alpha[..., None] * direction, axis=-1)
    return int(((alpha >= 0.5) & (residual < 12)).sum())


def series(label: str, x: list[float | int | str], mean: list[float | None]) -> Series:
    """A series whose interval is its mean +- 1 where there is a mean."""
    low = [None if m is None else m - 1.0 for m in mean]
    high = [None if m is None else m + 1.0 for m in mean]
    return Series(label, x, mean, low, high)


def sweep(label: str, offset: float) -> Series:
    return series(label, [1, 2, 5, 10], [3.0 + offset, 4.0 + offset, 6.0 + offset, 6.5 + offset])


def policies(label: str, offset: float) -> Series:
    names: list[float | int | str] = ["gradient", "q_learning", "random"]
    return series(label, names, [5.0 + offset, 8.0 + offset, 2.0 + offset])


# ---------------------------------------------------------------- metric_png


def test_numeric_sweep_draws_each_series_in_its_colour() -> None:
    image = decode(metric_png("total_steps", [sweep("a", 0), sweep("b", 2)], x_label="count"))
    assert size(image) == METRIC_SIZE
    assert distinct_colours(image) > 20
    assert pixels_of(image, BLUE) > 200
    assert pixels_of(image, ORANGE) > 200
    assert pixels_of(image, GREEN) == 0


def test_names_on_x_give_grouped_bars() -> None:
    image = decode(metric_png("success_rate", [policies("a", 0), policies("b", 1)], x_label="p"))
    assert size(image) == METRIC_SIZE
    # Bars fill far more pixels with the series colour than a line with markers does.
    assert pixels_of(image, BLUE) > 10_000
    assert pixels_of(image, ORANGE) > 10_000
    lines = decode(metric_png("success_rate", [sweep("a", 0), sweep("b", 1)], x_label="p"))
    assert pixels_of(lines, BLUE) < 5_000


@pytest.mark.parametrize(
    "x",
    [[1, "two", 3], [True, False, True]],
    ids=["numbers-and-names", "booleans"],
)
def test_anything_but_numbers_on_x_gives_bars(x: list[float | int | str]) -> None:
    image = decode(metric_png("m", [series("a", x, [2.0, 3.0, 4.0])], x_label=None))
    assert pixels_of(image, BLUE) > 10_000


def test_one_series_with_one_point_is_drawn() -> None:
    image = decode(metric_png("final_distance", [series("only", [5], [3.0])], x_label="count"))
    assert size(image) == METRIC_SIZE
    assert pixels_of(image, BLUE) > 20
    bar = decode(metric_png("final_distance", [series("only", ["one"], [3.0])], x_label=None))
    assert pixels_of(bar, BLUE) > 10_000


def test_a_missing_mean_leaves_a_gap_in_the_line() -> None:
    gap = decode(metric_png("m", [series("a", [0, 1, 2], [1.0, None, 1.0])], x_label=None))
    joined = decode(metric_png("m", [series("a", [0, 2], [1.0, 1.0])], x_label=None))
    # Same two points; only the joined one has a line across the axes between them.
    assert pixels_of(gap, BLUE) < 0.6 * pixels_of(joined, BLUE)


def test_a_missing_interval_draws_the_mean_without_error_bars() -> None:
    # The second series' wide interval sets the same y range in both pictures.
    wide = Series("b", [0], [0.0], [-10.0], [10.0])
    with_bar = Series("a", [0], [0.0], [-4.0], [4.0])
    bare = Series("a", [0], [0.0], [-4.0], [None])
    drawn_with = tinted(decode(metric_png("m", [with_bar, wide], x_label=None)), BLUE)
    drawn_bare = tinted(decode(metric_png("m", [bare, wide], x_label=None)), BLUE)
    assert drawn_bare > 20  # the marker
    assert drawn_with > drawn_bare + 150  # and a bar of about 150 pixels, with its caps


@pytest.mark.parametrize(
    "drawn",
    [[], [series("a", [1, 2], [None, None])], [Series("a", [], [], [], [])]],
    ids=["no-series", "all-none", "no-points"],
)
def test_nothing_to_draw_still_gives_a_picture_that_says_so(drawn: list[Series]) -> None:
    image = decode(metric_png("total_steps", drawn, x_label="count", title="A study"))
    assert size(image) == METRIC_SIZE
    assert pixels_of(image, BLUE) == 0
    centre = image[230:270, 300:500]  # where the message is written
    assert (centre.min(axis=-1) < 160).sum() > 100


def test_more_than_ten_series_all_get_drawn() -> None:
    many = [sweep(f"s{i}", i) for i in range(13)]
    image = decode(metric_png("m", many, x_label="x"))
    assert size(image) == METRIC_SIZE
    for colour in SERIES_COLOURS:
        assert pixels_of(image, colour) > 20


def test_series_with_unequal_lengths_are_refused() -> None:
    with pytest.raises(ValueError, match="one value per point"):
        Series("a", [1, 2, 3], [1.0, 2.0], [None, None], [None, None])


# ---------------------------------------------------------------- learning_png


def curve(label: str, episodes: int, level: float, band: bool = True) -> Series:
    x = list(range(episodes))
    mean = [level + 50.0 * np.exp(-e / max(episodes / 5, 1)) for e in x]
    low = [m - 5.0 for m in mean] if band else [None] * episodes
    high = [m + 5.0 for m in mean] if band else [None] * episodes
    return Series(label, x, mean, low, high)


def test_learning_panels_stack_three_inches_each() -> None:
    panels = {
        "steps per episode": [curve("a", 100, 100.0), curve("b", 100, 150.0)],
        "success rate": [curve("a", 100, 0.5), curve("b", 100, 0.2)],
    }
    image = decode(learning_png(panels, title="Learning"))
    assert size(image) == (800, 600)
    assert pixels_of(image, BLUE) > 200
    assert pixels_of(image, ORANGE) > 200
    assert size(decode(learning_png({"one": [curve("a", 10, 1.0)]}))) == (800, 300)


def test_learning_curves_have_translucent_bands_where_there_are_bounds() -> None:
    banded = decode(learning_png({"steps": [curve("a", 200, 100.0)]}))
    bare = decode(learning_png({"steps": [curve("a", 200, 100.0, band=False)]}))
    band_alpha = 0.2
    # Without bounds only the line's antialiased edges come near the band's colour.
    assert pixels_of(banded, BLUE, band_alpha) > 1_000
    assert pixels_of(bare, BLUE, band_alpha) < 100
    assert pixels_of(bare, BLUE) > 200


def test_a_label_keeps_its_colour_in_both_kinds_of_picture() -> None:
    # Colours follow the order in which labels first appear, in both functions.
    learning = decode(learning_png({"steps": [curve("first", 50, 1.0), curve("second", 50, 9.0)]}))
    metric = decode(metric_png("m", [sweep("first", 0), sweep("second", 3)], x_label=None))
    for image in (learning, metric):
        assert pixels_of(image, BLUE) > 100
        assert pixels_of(image, ORANGE) > 100
    alone = decode(learning_png({"steps": [curve("second", 50, 9.0)]}))
    assert pixels_of(alone, ORANGE) == 0


def test_twenty_thousand_episodes_are_drawn_from_bin_averages() -> None:
    rng = np.random.default_rng(4)
    x = list(range(20_000))
    mean = list(200.0 + rng.normal(0.0, 20.0, size=20_000))
    long_curve = Series("long", x, mean, [m - 10 for m in mean], [m + 10 for m in mean])
    image = decode(learning_png({"steps per episode": [long_curve, curve("short", 500, 150.0)]}))
    assert size(image) == (800, 300)
    assert pixels_of(image, BLUE) > 200
    assert pixels_of(image, ORANGE) > 200


def test_bin_averages_keep_at_most_the_limit_and_skip_gaps() -> None:
    x = np.arange(20_000, dtype=float)
    y = x.copy()
    y[10:20] = np.nan  # the whole second bin is missing
    y[25] = np.nan  # part of the third
    binned = charts.bin_average(np.vstack([x, y]), 2_000)
    assert binned.shape == (2, 2_000)
    assert binned[0, 0] == pytest.approx(4.5)
    assert np.isnan(binned[1, 1])
    assert binned[1, 2] == pytest.approx(np.mean([20, 21, 22, 23, 24, 26, 27, 28, 29]))
    assert binned[0, -1] == pytest.approx(19_994.5)
    short = np.vstack([x[:50], y[:50]])
    assert charts.bin_average(short, 2_000) is short


def test_learning_with_nothing_to_draw_says_so_in_each_panel() -> None:
    empty = decode(learning_png({}))
    assert size(empty) == (800, 300)
    panels = {"steps": [], "success rate": [series("a", [0, 1], [None, None])]}
    image = decode(learning_png(panels))
    assert size(image) == (800, 600)
    assert pixels_of(image, BLUE) == 0
    for middle in (140, 430):  # the centre of each panel
        band = image[middle - 15 : middle + 15, 300:500]
        assert (band.min(axis=-1) < 160).sum() > 100


def test_learning_curves_need_numeric_episodes() -> None:
    with pytest.raises(ValueError, match="numeric episodes"):
        learning_png({"steps": [series("a", ["one", "two"], [1.0, 2.0])]})


@pytest.mark.parametrize("x", [[0, 10, 30], ["gradient", "q_learning", "random"]])
def test_a_metric_that_cannot_be_negative_is_drawn_from_0(x: list[float | int | str]) -> None:
    """All-zero collisions drew on an axis from -0.04 to 0.04, as if collisions could be
    negative: from 0 (to 1 when all is 0), and small counts from 0 too."""
    zero = [Series("gradient", x, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0])]
    figure = charts.metric_figure("collisions", zero, x_label="obstacles", bounds=(0.0, np.inf))
    assert figure.axes[0].get_ylim() == (0.0, 1.0)
    some = [Series("gradient", x, [0.5, 2.0, 3.0], [0.1, 1.0, 2.0], [0.9, 3.0, 4.0])]
    figure = charts.metric_figure("collisions", some, x_label="obstacles", bounds=(0.0, np.inf))
    low, high = figure.axes[0].get_ylim()
    assert low == 0.0 and high >= 4.0
    unbounded = [Series("gradient", x, [-1.0, 0.0, 1.0], [-2.0, -1.0, 0.0], [0.0, 1.0, 2.0])]
    figure = charts.metric_figure("mean_return", unbounded, x_label="obstacles", bounds=None)
    assert figure.axes[0].get_ylim()[0] < -2.0
    image = decode(charts.metric_png("collisions", zero, x_label="obstacles",
                                     bounds=(0.0, np.inf)))  # fmt: skip
    assert size(image) == METRIC_SIZE


def test_every_habit_note_ends_inside_the_frame_and_the_image() -> None:
    """The note "..., 30 seeds" ran off the image and over the frame."""
    shares = {"approach": 0.6, "explore": 0.4}
    rows = [
        charts.HabitRow(
            f"robots.policy=q_learning\nstate {i}",
            shares,
            f"{27 + i}% of visits, mean gap 0.{i}3, 30 seeds",
        )
        for i in range(5)
    ]
    figure = charts.habits_figure(rows, title="a study")
    figure.draw_without_rendering()
    renderer = figure.canvas.get_renderer()  # type: ignore[attr-defined]
    ax = figure.axes[0]
    frame = ax.get_window_extent(renderer)
    notes = [t for t in ax.texts if "seeds" in t.get_text()]
    assert len(notes) == 5
    for note in notes:
        box = note.get_window_extent(renderer)
        assert box.x1 <= frame.x1 and box.x1 <= figure.bbox.x1
    assert ax.get_xlim()[0] == 0.0 and ax.get_xlim()[1] >= 1.5
    image = decode(charts.habits_png(rows, title="a study"))
    assert image.shape[1] == 1000


def test_paired_differences_are_drawn_beside_the_means_with_holm_marks() -> None:
    """A +1.3 effect whose means' intervals (tens wide) overlap: the forest panel draws it
    apart from 0, filled where Holm's p is below 0.05, hollow where not, and 'not tested'
    where there was no test."""
    series = [
        Series("gradient", [1, 15], [85.0, 84.0], [66.0, 66.0], [109.0, 107.0]),
        Series("q_learning", [1, 15], [86.3, 85.3], [67.0, 67.0], [110.0, 108.0]),
    ]
    differences = [
        charts.Difference("q_learning vs gradient\nrobots count: 1", 1.3, 0.9, 1.7, 0.008, 3),
        charts.Difference("q_learning vs gradient\nrobots count: 15", 0.4, -0.6, 1.4, 0.4, 3),
        charts.Difference("random vs gradient", None, None, None, None, None),
    ]
    figure = charts.metric_figure("total_steps", series, x_label="robots count",
                                  differences=differences)  # fmt: skip
    _, forest = figure.axes
    labels = [t.get_text() for t in forest.get_yticklabels()]
    assert labels == [d.label for d in differences]
    filled, hollow = forest.collections[-2:]  # the dots after the intervals
    assert offsets(filled).tolist() == [[1.3, 2.0]]  # the top row
    assert offsets(hollow).tolist() == [[0.4, 1.0]]
    said = [t.get_text() for t in forest.texts]
    assert said == ["p Holm 0.008 *", "p Holm 0.4", "not tested"]
    assert "Holm over 3" in forest.get_title()
    low, high = forest.get_xlim()
    assert low < 0.0 < 1.7 < high
    assert size(decode(png(figure))) == (1300, 500)  # wider than a metric alone


def test_a_metric_without_comparisons_is_one_panel() -> None:
    figure = charts.metric_figure("total_steps", [Series("a", [1], [2.0], [1.0], [3.0])],
                                  x_label=None)  # fmt: skip
    assert len(figure.axes) == 1
    assert size(decode(png(figure))) == METRIC_SIZE
