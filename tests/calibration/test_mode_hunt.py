"""The basin phase's hunt: peaks counted, the upper-bound batch's rule, no change when unimodal."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import torch
from scipy.special import logsumexp
from scipy.stats import qmc

from susp_bo.calibration import basin_search
from susp_bo.calibration.basin_search import BasinSettings, ascent_ends, basin_phase
from susp_bo.calibration.mode_hunt import hunt_batch, surrogate_peaks
from susp_bo.calibration.surrogate import Surrogate, SurrogateSettings
from susp_bo.calibration.surrogate_fit import fit_surrogate
from susp_bo.calibration.trust_region import posterior_reach

CENTRES = np.array([[0.2, 0.25], [0.75, 0.3], [0.6, 0.85]])
SD = 0.05


def two_modes(u: np.ndarray) -> np.ndarray:
    """Two equal Gaussian bumps in the unit square (nats)."""
    u = np.asarray(u)
    parts = [-0.5 * np.sum(((u - c) / SD) ** 2, axis=-1) for c in CENTRES[:2]]
    return logsumexp(np.stack(parts), axis=0)


def three_modes(u: np.ndarray) -> np.ndarray:
    """Three equal Gaussian bumps in the unit square (nats); ``_data`` misses the third."""
    u = np.asarray(u)
    parts = [-0.5 * np.sum(((u - c) / SD) ** 2, axis=-1) for c in CENTRES]
    return logsumexp(np.stack(parts), axis=0)


def one_mode(u: np.ndarray) -> np.ndarray:
    """One heavy-tailed bump at the first centre (nats; not quadratic, so the GP is unsure
    far from the data)."""
    return -3.0 * np.log1p(np.sum(((np.asarray(u) - CENTRES[0]) / SD) ** 2, axis=-1) / 6.0)


def _data(log_l) -> tuple[np.ndarray, np.ndarray]:
    """A Sobol' design with nothing near the third centre, and points around the first two."""
    rng = np.random.default_rng(3)
    design = qmc.Sobol(2, seed=1).random(16)
    design = design[np.max(np.abs(design - CENTRES[2]), axis=1) > 0.25]
    near = [c + SD * rng.normal(size=(8, 2)) for c in CENTRES[:2]]
    x = np.clip(np.vstack([design, *near]), 0.0, 1.0)
    return x, log_l(x)


def _fit(x: np.ndarray, y: np.ndarray) -> Surrogate:
    return fit_surrogate(x, y, SurrogateSettings(), seed=0)


def test_peaks_merge_ends_within_the_radius_and_skip_flat_ones() -> None:
    ends = np.array([[0.2, 0.2], [0.25, 0.2], [0.8, 0.8], [0.5, 0.5], [0.85, 0.75]])
    peaked = np.array([False, True, True, False, True])
    peaks = surrogate_peaks(ends, peaked, radius=0.1)
    # the best point's end counts even where flat; [0.5, 0.5] is flat; the others merge
    np.testing.assert_array_equal(peaks, ends[[0, 2]])
    assert surrogate_peaks(ends[:2], peaked[:2], radius=0.1).shape == (1, 2)


def test_a_peak_counts_only_where_its_best_start_confirms_it() -> None:
    ends = np.array([[0.2, 0.2], [0.8, 0.8], [0.81, 0.8], [0.5, 0.1]])
    peaked = np.ones(4, dtype=bool)
    # the second peak's best start is 5 nats below the surrogate's top there: unconfirmed,
    # and a lower start reaching the same peak does not confirm it either
    confirmed = np.array([True, False, True, True])
    np.testing.assert_array_equal(surrogate_peaks(ends, peaked, 0.1, confirmed), ends[[0, 3]])
    assert len(surrogate_peaks(ends, peaked, 0.1, np.zeros(4, dtype=bool))) == 0


def test_two_modes_count_two_peaks_and_one_mode_one() -> None:
    for log_l, expected in ((two_modes, 2), (one_mode, 1)):
        x, y = _data(log_l)
        _, ends, peaked = ascent_ends(x, y, _fit(x, y), radius=0.1, depth=20.0)
        assert len(surrogate_peaks(ends, peaked, 0.1)) == expected, log_l.__name__


@pytest.mark.parametrize("beta", [3.0, 12.0])
def test_the_hunt_batch_keeps_its_rule(beta: float) -> None:
    x, y = _data(two_modes)
    surrogate = _fit(x, y)
    _, ends, _ = ascent_ends(x, y, surrogate, radius=0.1, depth=20.0)
    best, reach = float(y.max()), posterior_reach(2)
    batch = hunt_batch(surrogate, best, reach, 6, 0.1, beta, seed=5, known=ends)
    assert batch.ndim == 2 and batch.shape[1] == 2 and len(batch) <= 6
    assert np.all((batch >= 0.0) & (batch <= 1.0))
    with torch.no_grad():
        mean, sd = surrogate.log_likelihood_uncertainty(torch.as_tensor(batch))
    bound = (mean + beta * sd).numpy()
    assert np.all(bound >= best - reach)  # each can still hold posterior mass
    assert np.all(np.diff(bound) <= 1e-12)  # the highest bound first
    if len(batch):  # away from the known modes and from each other
        assert np.min(np.max(np.abs(batch[:, None] - ends[None]), axis=-1)) >= 0.1
        gaps = np.max(np.abs(batch[:, None] - batch[None]), axis=-1)
        assert np.all(gaps[~np.eye(len(batch), dtype=bool)] >= 0.1)
    if beta == 12.0:  # a bound this wide reaches far from the data: the hunt looks there
        assert len(batch) >= 1


def test_no_hunt_where_no_bound_reaches() -> None:
    x, y = _data(two_modes)
    surrogate = _fit(x, y)
    _, ends, _ = ascent_ends(x, y, surrogate, radius=0.1, depth=20.0)
    # a best value far above anything the surrogate allows: nothing can hold the mass
    assert hunt_batch(surrogate, 1e6, 1.0, 6, 0.1, 3.0, seed=5, known=ends).shape == (0, 2)


def _phase(log_l, hunt_beta: float) -> tuple[list, list[np.ndarray]]:
    x, y = _data(log_l)
    calls: list[np.ndarray] = []

    def evaluate(u: np.ndarray) -> np.ndarray:
        calls.append(u.copy())
        return log_l(u)

    settings = BasinSettings(hunt_beta=hunt_beta)
    climbs = basin_phase(x, y, 24, 4, settings, _fit, evaluate, lambda: 5, 4, 128).climbs
    return climbs, calls


def test_with_one_peak_the_hunt_changes_nothing() -> None:
    x, y = _data(one_mode)
    surrogate = _fit(x, y)
    _, ends, _ = ascent_ends(x, y, surrogate, radius=0.1, depth=20.0)
    best, reach = float(y.max()), posterior_reach(2)
    assert len(hunt_batch(surrogate, best, reach, 4, 0.1, 50.0, seed=5, known=ends))
    # a bound that wide would hunt; one peak is why the phase does not
    on, calls_on = _phase(one_mode, 50.0)
    off, calls_off = _phase(one_mode, 0.0)
    assert [c.stop_reason for c in on] == [c.stop_reason for c in off]
    assert len(calls_on) == len(calls_off)
    for a, b in zip(calls_on, calls_off):
        np.testing.assert_array_equal(a, b)


def test_with_two_peaks_the_phase_hunts_first_within_its_share() -> None:
    climbs, calls = _phase(two_modes, 12.0)
    hunts = [c for c in climbs if c.stop_reason == "hunt"]
    assert hunts and climbs[0].stop_reason == "hunt"
    assert sum(c.n_evaluations for c in hunts) <= int(BasinSettings().hunt_fraction * 24)
    assert sum(c.n_evaluations for c in climbs) == sum(len(c) for c in calls) <= 24
    for hunt in hunts:  # the report: from the best point to the batch's best
        assert hunt.start_log_likelihood == pytest.approx(float(_data(two_modes)[1].max()))
        assert hunt.end_log_likelihood == pytest.approx(float(two_modes(hunt.end[None])[0]))
    # there is no third mode: the first batch lands below the posterior's reach of the best
    assert len(hunts) == 1
    assert hunts[0].end_log_likelihood < hunts[0].start_log_likelihood - posterior_reach(2)
    assert BasinSettings().hunt_beta == 3.0  # on by default (session 43)
    off, off_calls = _phase(two_modes, 0.0)  # without the hunt
    assert off == [] and off_calls == []  # both modes evaluated: nothing to climb


@pytest.mark.parametrize("batch_best", ["real", "found", "nan"])
def test_a_fruitless_hunt_batch_ends_the_hunt(monkeypatch, batch_best: str) -> None:
    """Session 43: the first batch with nothing within the posterior's reach of the best
    (or nothing finite) ends the hunt. With a wide bound (beta 50) on two modes and no third,
    the batches would go on to the hunts' share if each had found something."""
    real = basin_search._hunt
    batches: list[int] = []

    def recorded(*args, **kwargs):
        x, y, report = real(*args, **kwargs)
        if report is not None:
            batches.append(report.n_evaluations)
            if batch_best != "real":  # what the phase is told the batch's best was
                end = report.start_log_likelihood if batch_best == "found" else float("nan")
                report = replace(report, end_log_likelihood=end)
        return x, y, report

    monkeypatch.setattr(basin_search, "_hunt", recorded)
    climbs, _ = _phase(two_modes, 50.0)
    hunts = [c for c in climbs if c.stop_reason == "hunt"]
    if batch_best == "found":
        assert len(batches) >= 3 and sum(batches) <= int(BasinSettings().hunt_fraction * 24)
    else:
        assert len(batches) == len(hunts) == 1
    if batch_best == "real":
        assert hunts[0].end_log_likelihood < hunts[0].start_log_likelihood - posterior_reach(2)


def test_a_hunt_that_finds_a_mode_goes_on_until_a_batch_finds_nothing() -> None:
    climbs, _ = _phase(three_modes, 12.0)
    hunts = [c for c in climbs if c.stop_reason == "hunt"]
    reach = posterior_reach(2)
    # the first batch reaches the hidden mode's slope (within the reach of the best); the
    # hunt goes on; the first batch below the reach ends it
    assert hunts[0].end_log_likelihood >= hunts[0].start_log_likelihood - reach
    fruitless = [h.end_log_likelihood < h.start_log_likelihood - reach for h in hunts]
    assert fruitless[-1] and not any(fruitless[:-1])
    # and the phase then climbs the mode the hunt found to its top
    assert climbs[-1].stop_reason != "hunt" and climbs[-1].end_log_likelihood > -0.5
    assert np.max(np.abs(climbs[-1].end - CENTRES[2])) < SD


def test_a_mode_seen_only_at_its_fringe_is_climbed_not_hunted() -> None:
    # the second mode has two evaluations 2.5 sd from its centre (3 nats below its top):
    # its peak is not confirmed, so the phase climbs it as before and does not hunt
    x, _ = _data(two_modes)
    x = np.vstack([x[:-8], CENTRES[1] + SD * np.array([[2.5, 0.0], [0.0, -2.5]])])
    y = two_modes(x)
    calls: list[np.ndarray] = []

    def evaluate(u: np.ndarray) -> np.ndarray:
        calls.append(u.copy())
        return two_modes(u)

    outcome = basin_phase(
        x, y, 24, 4, BasinSettings(hunt_beta=12.0), _fit, evaluate, lambda: 5, 4, 128
    )
    climbs = outcome.climbs
    assert outcome.confirmed_peaks >= 1  # the first mode; the climb confirms the second
    assert climbs and all(c.stop_reason != "hunt" for c in climbs)
    assert climbs[0].end_log_likelihood > -0.5  # the climb reached the second mode's top


def test_a_second_peak_that_only_a_climb_confirms_starts_no_hunt() -> None:
    """One confirmed peak when the global search ended, and a climb that confirms a second
    (a curved ridge's two ends look so): the phase does not hunt, and makes exactly the
    evaluations it makes without the hunt (session 43: on the curved 5-D chain the hunt
    then cost MMTV .024 -> .067)."""
    x, _ = _data(three_modes)
    x = np.vstack([x[:-8], CENTRES[1] + SD * np.array([[2.5, 0.0], [0.0, -2.5]])])
    y = three_modes(x)
    runs = {}
    for beta in (12.0, 0.0):
        calls: list[np.ndarray] = []

        def evaluate(u: np.ndarray, calls: list[np.ndarray] = calls) -> np.ndarray:
            calls.append(u.copy())
            return three_modes(u)

        settings = BasinSettings(hunt_beta=beta)
        outcome = basin_phase(x, y, 40, 4, settings, _fit, evaluate, lambda: 5, 4, 128)
        runs[beta] = (outcome, calls)
    (hunted, calls_on), (plain, calls_off) = runs[12.0], runs[0.0]
    assert hunted.climbs and hunted.climbs[0].end_log_likelihood > -0.5  # the climb confirms
    assert hunted.confirmed_peaks >= 2  # a second peak, after the climb
    assert all(c.stop_reason != "hunt" for c in hunted.climbs)
    assert [c.stop_reason for c in hunted.climbs] == [c.stop_reason for c in plain.climbs]
    assert len(calls_on) == len(calls_off)
    for a, b in zip(calls_on, calls_off):
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize(
    ("field", "value"), [("hunt_beta", -1.0), ("hunt_fraction", 0.0), ("hunt_fraction", 1.5)]
)
def test_bad_hunt_settings_are_refused(field: str, value: float) -> None:
    with pytest.raises(ValueError, match=field):
        BasinSettings(**{field: value})


def test_calibrate_hunts_only_in_a_global_search_with_fixed_noise(monkeypatch) -> None:
    """The hunt (on by default, session 43) reaches the basin phase of a search over C_w
    with a fixed noise; with a trust region or a learned noise the phase runs without it,
    as with the local phase (the demo's and the paired studies' path)."""
    from susp_bo.calibration import loop
    from susp_bo.calibration.loop import CalibrationSettings, calibrate
    from susp_bo.calibration.test_functions import TARGETS

    real = loop.run_basin_phase
    seen: list[float] = []

    def spy(*args, **kwargs):
        seen.append(args[6].basin.hunt_beta)  # the settings the phase runs with
        return real(*args, **kwargs)

    monkeypatch.setattr(loop, "run_basin_phase", spy)
    target = TARGETS["banana_2d"]()
    small = CalibrationSettings(max_evaluations=24, batch_size=4, mcmc_chains=8,
                                mcmc_warmup=50, mcmc_samples=50, candidate_count=64,
                                check_points=0)  # fmt: skip
    runs = {
        "global": small,
        "trust region": replace(small, trust_region=True),
        "learned noise": replace(small, surrogate=SurrogateSettings(noise="learned")),
    }
    for settings in runs.values():
        assert settings.basin.hunt_beta == 3.0
        calibrate(target, target.bounds, target.names, settings, progress=False)
    assert seen == [3.0, 0.0, 0.0]
