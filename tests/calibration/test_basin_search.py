"""Basin phase: secondary basins of the surrogate, local climbs, no change when unimodal."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import torch
from scipy.special import logsumexp
from scipy.stats import qmc

from susp_bo.calibration.basin_search import BasinSettings, climb, secondary_basins
from susp_bo.calibration.loop import CalibrationSettings, calibrate
from susp_bo.calibration.surrogate import Surrogate, SurrogateSettings
from susp_bo.calibration.surrogate_fit import fit_surrogate

CENTRES = np.array([[0.25, 0.3], [0.75, 0.7]])
SD = 0.05


def log_l(u: np.ndarray, weights: tuple[float, float] = (0.6, 0.4)) -> np.ndarray:
    """Two separated Gaussian bumps in the unit square (nats)."""
    parts = [
        np.log(w) - 0.5 * np.sum(((u - c) / SD) ** 2, axis=-1) for w, c in zip(weights, CENTRES)
    ]
    return logsumexp(np.stack(parts), axis=0)


def log_l_one(u: np.ndarray) -> np.ndarray:
    """The first bump alone (nats)."""
    return -0.5 * np.sum(((np.asarray(u) - CENTRES[0]) / SD) ** 2, axis=-1)


def _data(with_fringe: bool) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(3)
    design = qmc.Sobol(2, seed=1).random(16)
    near_a = CENTRES[0] + SD * rng.normal(size=(10, 2))
    parts = [design, near_a]
    if with_fringe:  # two points 2.5 sd from the second centre, nothing nearer
        parts.append(CENTRES[1] + SD * np.array([[2.5, 0.0], [0.0, -2.5]]))
    x = np.clip(np.vstack(parts), 0.0, 1.0)
    return x, log_l(x)


def _surrogate(x: np.ndarray, y: np.ndarray) -> Surrogate:
    return fit_surrogate(x, y, SurrogateSettings(), seed=0)


def test_a_mode_seen_only_at_its_fringe_is_a_secondary_basin() -> None:
    x, y = _data(with_fringe=True)
    found = secondary_basins(x, y, _surrogate(x, y), radius=0.1, depth=20.0)
    fringe = {len(x) - 2, len(x) - 1}
    assert found and found[0] in fringe, found
    # explored once (its head and where its climb ended), it is not offered again
    explored = np.vstack([x[found[0]], CENTRES[1]])
    again = secondary_basins(x, y, _surrogate(x, y), 0.1, 20.0, exclude=explored)
    assert not set(again) & fringe


def test_a_design_point_near_the_second_mode_heads_a_basin() -> None:
    x, y = _data(with_fringe=False)  # no fringe points, but a design point 7 nats down
    found = secondary_basins(x, y, _surrogate(x, y), radius=0.1, depth=20.0)
    assert len(found) == 1 and np.max(np.abs(x[found[0]] - CENTRES[1])) < 0.2
    assert y[found[0]] < float(log_l(CENTRES[1][None])[0]) - 5.0


def test_one_mode_has_no_secondary_basin() -> None:
    x, _ = _data(with_fringe=False)
    y = log_l_one(x)
    assert secondary_basins(x, y, _surrogate(x, y), radius=0.1, depth=20.0) == []


def test_the_climb_reaches_the_peak_of_the_fringe_mode() -> None:
    x, y = _data(with_fringe=True)
    start = len(x) - 1
    peak = float(log_l(CENTRES[1][None])[0])
    assert y[start] < peak - 3.0
    _, y_out, report = climb(
        x,
        y,
        start,
        budget=32,
        batch_size=4,
        settings=BasinSettings(),
        fit=_surrogate,
        evaluate=log_l,
        seed=lambda: 100,
        restarts=4,
        raw_samples=128,
        known=CENTRES[:1],
    )
    assert report.n_evaluations == len(y_out) - len(y) <= 32
    assert report.end_log_likelihood > peak - 0.5, (report.end_log_likelihood, peak)
    assert np.max(np.abs(report.end - CENTRES[1])) < SD
    assert report.stop_reason in ("narrow", "budget")


def test_a_climb_into_the_best_basin_stops_as_merged() -> None:
    x, _ = _data(with_fringe=False)
    # a lone point 3 sd from the first centre, on the side away from its other points
    x = np.vstack([x, np.clip(CENTRES[0] + SD * np.array([3.0, 3.0]), 0, 1)[None]])
    y = log_l_one(x)
    _, _, report = climb(
        x, y, len(x) - 1, 40, 4, BasinSettings(), _surrogate, log_l_one, lambda: 0, 4, 128,
        x[np.argmax(y)][None],
    )  # fmt: skip
    assert report.stop_reason == "merged"
    assert report.n_evaluations < 40


def test_without_a_secondary_basin_the_phase_changes_nothing() -> None:
    bounds, names = np.array([[0.0, 0.0], [1.0, 1.0]]), ("a", "b")
    settings = CalibrationSettings(
        seed=0, max_evaluations=40, batch_size=4, mcmc_chains=8, mcmc_warmup=100,
        mcmc_samples=100, candidate_count=64, check_points=0,
    )  # fmt: skip
    on = calibrate(log_l_one, bounds, names, settings, progress=False)
    off = calibrate(log_l_one, bounds, names, replace(settings, basin_search=False), progress=False)
    assert [h.phase for h in on.history].count("ego") >= 1
    assert on.basins == () and on.to_dict()["basin_climbs"] == []
    np.testing.assert_array_equal(on.X, off.X)
    np.testing.assert_array_equal(on.draws, off.draws)


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("radius", 0.0, "radius"),
        ("depth", -1.0, "depth"),
        ("initial_half_width", 0.7, "initial_half_width"),
        ("min_half_width", 0.1, "half-widths"),
        ("max_basins", 0, "max_basins"),
        ("budget_fraction", 1.0, "budget_fraction"),
    ],
)
def test_bad_settings_are_refused_by_name(field: str, value: float, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        BasinSettings(**{field: value})


def test_the_box_and_incumbent_of_the_acquisition_are_honoured() -> None:
    from susp_bo.calibration.acquisition import propose_ei_batch

    x, y = _data(with_fringe=True)
    surrogate = _surrogate(x, y)
    box = torch.tensor([[0.6, 0.55], [0.8, 0.75]], dtype=torch.float64)
    u, _ = propose_ei_batch(surrogate, 3, 0, 4, 128, box=box, best_f=float(y[-1]))
    assert torch.all(u >= box[0] - 1e-12) and torch.all(u <= box[1] + 1e-12)
    with pytest.raises(ValueError, match="box"):
        propose_ei_batch(surrogate, 1, 0, 2, 16, box=box[:, :1])


def _small(**kw: object) -> CalibrationSettings:
    return CalibrationSettings(
        seed=0, max_evaluations=40, batch_size=4, mcmc_chains=8, mcmc_warmup=100,
        mcmc_samples=100, candidate_count=64, check_points=0, **kw,  # type: ignore[arg-type]
    )  # fmt: skip


def test_several_confirmed_modes_make_the_refinement_optimistic_and_say_so() -> None:
    """Two bumps both found: the basin phase counts two confirmed peaks, and the rest of
    the refinement runs with refine_optimism = modes_refine_optimism (recorded)."""
    bounds, names = np.array([[0.0, 0.0], [1.0, 1.0]]), ("a", "b")
    on = calibrate(log_l, bounds, names, _small(), progress=False)
    off = calibrate(log_l, bounds, names, _small(modes_refine_optimism=0.0), progress=False)
    assert on.modes_optimism_at is not None
    assert on.to_dict()["modes_refine_optimism_from_evaluation"] == on.modes_optimism_at
    assert off.modes_optimism_at is None
    assert "modes_refine_optimism_from_evaluation" not in off.to_dict()
    # the same run up to the switch, another one after it
    n = on.modes_optimism_at
    np.testing.assert_array_equal(on.X[:n], off.X[:n])
    assert not np.array_equal(on.X, off.X)


def test_one_mode_leaves_the_refinement_as_it_was() -> None:
    bounds, names = np.array([[0.0, 0.0], [1.0, 1.0]]), ("a", "b")
    on = calibrate(log_l_one, bounds, names, _small(), progress=False)
    off = calibrate(log_l_one, bounds, names, _small(modes_refine_optimism=0.0), progress=False)
    assert on.modes_optimism_at is None
    np.testing.assert_array_equal(on.X, off.X)
    np.testing.assert_array_equal(on.draws, off.draws)


def test_a_bad_modes_refine_optimism_is_refused() -> None:
    with pytest.raises(ValueError, match="modes_refine_optimism: -1"):
        CalibrationSettings(modes_refine_optimism=-1.0)
