"""The biomarker fields: their values follow the paper's formulas and their analytic gradients
equal finite differences."""

import math

import numpy as np
import pytest

from nanonav.engine import field_and_gradient
from nanonav.scenario import Biomarker, FieldModel

MODELS: list[FieldModel] = ["gaussian", "inverse_square", "diffusion"]


def _world(model: FieldModel, seed: int = 3) -> tuple[Biomarker, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    biomarker = Biomarker(model=model, emitters_per_cell=20, emitter_scatter=1.5, spread=6.0)
    cells = rng.uniform(-10, 10, (2, 3))
    offsets = rng.normal(0, 1.5, (2, 20 if model == "inverse_square" else 0, 3))
    return biomarker, cells, offsets


@pytest.mark.parametrize("model", MODELS)
def test_analytic_gradient_equals_finite_differences(model: FieldModel) -> None:
    biomarker, cells, offsets = _world(model)
    points = np.random.default_rng(7).uniform(-20, 20, (200, 3))
    _, grad = field_and_gradient(biomarker, cells, offsets, points)
    h = 1e-5
    numeric = np.empty_like(grad)
    for axis in range(3):
        step = np.zeros(3)
        step[axis] = h
        up, _ = field_and_gradient(biomarker, cells, offsets, points + step)
        down, _ = field_and_gradient(biomarker, cells, offsets, points - step)
        numeric[:, axis] = (up - down) / (2 * h)
    scale = np.abs(numeric).max(axis=1, keepdims=True)
    np.testing.assert_allclose(grad, numeric, rtol=1e-5, atol=1e-7 * float(scale.max()))
    assert np.abs(grad).max() > 0


def test_gaussian_follows_equation_2_1() -> None:
    biomarker = Biomarker(model="gaussian", peak=2.0, spread=4.0)
    cells = np.array([[1.0, 2.0, 3.0]])
    points = np.array([[1.0, 2.0, 3.0], [5.0, 2.0, 3.0], [1.0, 2.0, -5.0]])
    conc, grad = field_and_gradient(biomarker, cells, np.zeros((1, 0, 3)), points)
    np.testing.assert_allclose(conc, [2.0, 2.0 * math.exp(-0.5), 2.0 * math.exp(-2.0)])
    # eq. 2.2: d rho / dx = -(x - x0) / sigma^2 rho
    np.testing.assert_allclose(grad[1], [-(4.0 / 16.0) * conc[1], 0.0, 0.0], atol=1e-15)


def test_inverse_square_sums_softened_emitters() -> None:
    biomarker = Biomarker(model="inverse_square", peak=4.0, emitters_per_cell=2, softening=0.5)
    cells = np.zeros((1, 3))
    offsets = np.array([[[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]]])
    point = np.array([[0.0, 3.0, 0.0]])
    conc, _ = field_and_gradient(biomarker, cells, offsets, point)
    expected = 2 * 2.0 / (1.0 + 9.0 + 0.25)
    assert conc[0] == pytest.approx(expected, rel=1e-12)
    at_emitter, grad = field_and_gradient(biomarker, cells, offsets, np.array([[1.0, 0, 0]]))
    assert np.isfinite(at_emitter).all() and np.isfinite(grad).all()


def test_diffusion_decays_exponentially_beyond_inverse_distance() -> None:
    biomarker = Biomarker(model="diffusion", peak=1.0, decay_length=5.0, softening=1e-6)
    cells = np.zeros((1, 3))
    r = np.array([[2.0, 0, 0], [4.0, 0, 0]])
    conc, _ = field_and_gradient(biomarker, cells, np.zeros((1, 0, 3)), r)
    np.testing.assert_allclose(conc, np.exp(-r[:, 0] / 5.0) / r[:, 0], rtol=1e-9)
    at_source, grad = field_and_gradient(biomarker, cells, np.zeros((1, 0, 3)), np.zeros((1, 3)))
    assert np.isfinite(at_source).all() and np.isfinite(grad).all()


@pytest.mark.parametrize("model", MODELS)
def test_gradient_points_toward_a_lone_cell(model: FieldModel) -> None:
    biomarker = Biomarker(model=model, emitter_scatter=0.0)
    cells = np.array([[0.0, 0.0, 0.0]])
    offsets = np.zeros((1, 50 if model == "inverse_square" else 0, 3))
    points = np.random.default_rng(1).uniform(-20, 20, (50, 3))
    _, grad = field_and_gradient(biomarker, cells, offsets, points)
    cosine = -(grad * points).sum(axis=1) / (
        np.linalg.norm(grad, axis=1) * np.linalg.norm(points, axis=1)
    )
    np.testing.assert_allclose(cosine, 1.0, rtol=1e-9)
