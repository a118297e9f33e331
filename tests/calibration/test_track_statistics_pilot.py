"""The summary likelihood's two-stage pilot on a linear model whose fit is known exactly."""

from __future__ import annotations

import numpy as np
import pytest

from susp_bo.calibration.track_statistics import summary_residuals
from susp_bo.calibration.track_statistics_pilot import (
    STEP,
    mean_jacobian,
    summary_fit,
    two_stage_error,
)

C, F, Q, MU, NU, M = 2, 12, 2, 3, 3, 60
BOUNDS = np.array([[10.0, -2.0], [30.0, 6.0]])


class LinearModel:
    """Spectra linear in w: m(w) = m0 + G (w − lower), runs scattered by a correlated Σ."""

    def __init__(self, seed: int) -> None:
        rng = np.random.default_rng(seed)
        self.m0 = rng.normal(size=(C, F))
        self.gradient = rng.normal(size=(Q, C, F)) / (BOUNDS[1] - BOUNDS[0])[:, None, None]
        mixing = rng.normal(size=(C * F, C * F)) * 0.05 + np.eye(C * F) * 0.1
        self.mixing = mixing
        self.model_offsets = self.draws(rng, MU)  # the μ fixed model tracks
        self.rows = 0
        self.pilot_calls: list[tuple[tuple[float, ...], int]] = []

    def mean(self, W: np.ndarray) -> np.ndarray:
        return self.m0 + np.einsum("bq,qcf->bcf", np.atleast_2d(W) - BOUNDS[0], self.gradient)

    def draws(self, rng: np.random.Generator, n: int) -> np.ndarray:
        return (rng.normal(size=(n, C * F)) @ self.mixing.T).reshape(n, C, F)

    def spectra(self, W: np.ndarray) -> np.ndarray:
        self.rows += len(np.atleast_2d(W))
        return self.mean(W)[:, None] + self.model_offsets[None]

    def pilot(self, w: np.ndarray, stage: int) -> np.ndarray:
        self.pilot_calls.append((tuple(w.tolist()), stage))
        return self.mean(w[None])[0] + self.draws(np.random.default_rng([99, stage]), M)


def _measured(model: LinearModel, u_true: np.ndarray) -> np.ndarray:
    w = BOUNDS[0] + u_true * (BOUNDS[1] - BOUNDS[0])
    return model.mean(w[None])[0] + model.draws(np.random.default_rng(5), NU)


def test_the_first_fit_is_the_exact_root_of_the_summaries_and_stage_two_runs_there() -> None:
    model = LinearModel(1)
    measured = _measured(model, np.array([0.3, 0.7]))
    error, record = two_stage_error(model.spectra, model.pilot, measured, BOUNDS, MU)
    rows = model.rows
    # stage 1 at the middle of C_w, stage 2 at the first fit (physical units)
    assert [stage for _, stage in model.pilot_calls] == [0, 1]
    np.testing.assert_allclose(model.pilot_calls[0][0], BOUNDS.mean(axis=0))
    u1 = np.array(record.first_fit)
    np.testing.assert_allclose(
        model.pilot_calls[1][0], BOUNDS[0] + u1 * (BOUNDS[1] - BOUNDS[0]), rtol=1e-12
    )
    assert record.converged
    # the root of Aᵀ(ȳ − h̄(u)) = 0 of the first stage's weights, solved directly
    first_weights = _first_stage_weights(model, measured)
    span = BOUNDS[1] - BOUNDS[0]
    g = (model.gradient * span[:, None, None]).reshape(Q, -1)  # d h̄ / d u
    base = (measured.mean(axis=0) - model.m0 - model.model_offsets.mean(axis=0)).reshape(-1)
    exact = np.linalg.solve(first_weights.T @ g.T, first_weights.T @ base)
    np.testing.assert_allclose(u1, exact, atol=1e-6)
    # the final error: ν, μ, M as given; the summaries vanish at the fit
    assert (error.n_measured, error.n_simulated, error.pilot_runs) == (NU, MU, M)
    assert record.shrinkage == error.shrinkage
    # every simulation counted: 2 M pilot runs and μ per model-track point
    assert record.simulations == 2 * M + MU * rows


def _first_stage_weights(model: LinearModel, measured: np.ndarray) -> np.ndarray:
    """The first stage's A (p x q), rebuilt by running it alone."""
    from susp_bo.calibration.track_statistics_pilot import pilot_error

    first = pilot_error(
        model.spectra, model.pilot, NU, MU, BOUNDS, np.full(Q, 0.5), 0
    )  # same pilot draws (seeded by stage)
    return first.weights.reshape(-1, Q)


def test_the_mean_jacobian_is_the_model_gradient_in_unit_coordinates() -> None:
    model = LinearModel(2)
    jacobian = mean_jacobian(model.spectra, BOUNDS, np.array([0.5, 1.0]))  # one face: one-sided
    span = BOUNDS[1] - BOUNDS[0]
    np.testing.assert_allclose(jacobian, model.gradient * span[:, None, None], rtol=1e-6)
    assert model.rows == 2 * Q
    assert STEP < 1e-3


def test_a_root_outside_the_box_stops_at_its_face_and_too_few_steps_are_not_converged() -> None:
    model = LinearModel(3)
    measured = _measured(model, np.array([0.5, 0.5]))
    error, _ = two_stage_error(model.spectra, model.pilot, measured, BOUNDS, MU)
    far = measured + 5.0 * model.gradient[0] * (BOUNDS[1, 0] - BOUNDS[0, 0])  # beyond C_w
    u, _ = summary_fit(model.spectra, far, error, BOUNDS, np.full(Q, 0.5))
    assert np.all((u >= 0.0) & (u <= 1.0))
    assert u[0] == pytest.approx(1.0)
    _, converged_once = summary_fit(
        model.spectra, measured, error, BOUNDS, np.full(Q, 0.05), iterations=1
    )
    assert not converged_once
    u_ok, converged_ok = summary_fit(model.spectra, measured, error, BOUNDS, np.full(Q, 0.05))
    assert converged_ok
    w_ok = BOUNDS[0] + u_ok * (BOUNDS[1] - BOUNDS[0])
    np.testing.assert_allclose(
        summary_residuals(measured, model.spectra(w_ok[None])[0], error), 0.0, atol=1e-6
    )


def test_a_pilot_too_small_for_q_is_refused_naming_the_minimum() -> None:
    model = LinearModel(4)

    def small(w: np.ndarray, stage: int) -> np.ndarray:
        return model.pilot(w, stage)[:20]

    with pytest.raises(ValueError, match="pilot: 20 runs; need at least 50"):
        two_stage_error(model.spectra, small, _measured(model, np.full(Q, 0.5)), BOUNDS, MU)
