"""The posterior figures: files written, and drawn from the numbers they are given."""

from __future__ import annotations

from pathlib import Path

import matplotlib.image
import numpy as np

from susp_bo import plots
from susp_bo.calibration.posterior import PosteriorSummary


def _summary(q: int, rng: np.random.Generator) -> tuple[PosteriorSummary, np.ndarray, np.ndarray]:
    bounds = np.vstack([np.zeros(q), np.linspace(1.0, 10.0, q)])
    samples = bounds[0] + (bounds[1] - bounds[0]) * rng.beta(8.0, 4.0, size=(4000, q))
    centre = np.median(samples, axis=0)
    summary = PosteriorSummary(
        names=tuple(f"p{k}" for k in range(q)),
        joint_map=centre,
        marginal_map=centre,
        interval95=np.quantile(samples, [0.025, 0.975], axis=0).T,
        equal_tailed95=np.quantile(samples, [0.025, 0.975], axis=0).T,
        mean=samples.mean(axis=0),
        sd=samples.std(axis=0),
        r_hat=np.ones(q),
        ess=np.full(q, 4000.0),
    )
    return summary, samples, bounds


def test_posterior_figures_writes_the_three_pngs(tmp_path: Path, rng: np.random.Generator) -> None:
    summary, samples, bounds = _summary(3, rng)
    paths = plots.posterior_figures(summary, samples, bounds, tmp_path, reference=centre_of(bounds))
    assert [p.name for p in paths] == [plots.FIG1_NAME, plots.FIG2_NAME, plots.PAIRS_NAME]
    for path in paths:
        image = matplotlib.image.imread(path)
        assert image.shape[0] > 200 and image.shape[1] > 200
        assert np.std(image) > 0.01  # not a blank canvas


def test_fig1_changes_when_the_reference_moves(tmp_path: Path, rng: np.random.Generator) -> None:
    summary, _, bounds = _summary(2, rng)
    a = plots.plot_parameters(summary, bounds, tmp_path / "a.png", reference=bounds[0])
    b = plots.plot_parameters(summary, bounds, tmp_path / "b.png", reference=bounds[1])
    assert not np.array_equal(matplotlib.image.imread(a), matplotlib.image.imread(b))


def centre_of(bounds: np.ndarray) -> np.ndarray:
    return bounds.mean(axis=0)


def test_fig2_and_pairs_follow_the_draws(tmp_path: Path, rng: np.random.Generator) -> None:
    summary, samples, bounds = _summary(2, rng)
    a = plots.plot_marginals(samples, summary, bounds, tmp_path / "a.png", units=["m", "s"])
    b = plots.plot_marginals(0.5 * samples, summary, bounds, tmp_path / "b.png")
    assert not np.array_equal(matplotlib.image.imread(a), matplotlib.image.imread(b))
    p = plots.plot_pairs(samples, summary, bounds, tmp_path / "p.png", reference=bounds[0])
    assert matplotlib.image.imread(p).shape[0] > 200
