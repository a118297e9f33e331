"""The posterior figures: files written, drawn from the numbers given, readable by an engineer.

Readable here means: physical units with SI prefixes and no offset text on any axis, each
marginal zoomed to where its mass is, a legend naming every element drawn, and the
reliability verdict in the title.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib.colors
import matplotlib.image
import matplotlib.pyplot as plt
import numpy as np
import pytest
from matplotlib.figure import Figure

from susp_bo import plots
from susp_bo.calibration.posterior import PosteriorSummary, summarize
from susp_bo.posterior_plots.common import NOT_TRUSTED_COLOR, TRUSTED_COLOR, view_of
from susp_bo.posterior_plots.pairs import density2d, hpd_levels

NOT_TRUSTED = {
    "verdict": "not_trusted",
    "reasons": [
        {"code": "budget_too_small", "message": "40 evaluations, q = 7 needs 90"},
        {"code": "poor_mixing", "message": "R-hat 1.2"},
    ],
    "sentence": "Not trusted: the budget is too small and the chains did not mix.",
}
TRUSTED = {"verdict": "trusted", "reasons": [], "sentence": "Trusted: all checks passed."}


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


def _dampers(rng: np.random.Generator) -> dict:
    """A narrow and a wide damper posterior in N·s/m (the demo's two worn dampers)."""
    bounds = np.array([[15.0e3, 0.5e6], [80.0e3, 8.0e6]])
    draws = np.column_stack([rng.normal(28.0e3, 350.0, 4000), rng.normal(4.4e6, 0.5e6, 4000)])
    draws = np.clip(draws, bounds[0], bounds[1])
    summary = summarize(
        ((draws - bounds[0]) / (bounds[1] - bounds[0])).reshape(4, 1000, 2),
        bounds,
        ("secondary_vertical_damping", "yaw_damper_damping"),
    )
    return {
        "summary": summary,
        "draws": draws,
        "bounds": bounds,
        "reference": np.array([28.0e3, 3.7e6]),
        "units": ("N·s/m", "N·s/m"),
        "acceptable": np.array([[32.0e3, 3.9e6], [48.0e3, 6.5e6]]),
    }


def _drawn(fig: Figure) -> Figure:
    fig.canvas.draw()  # tick labels and offset texts exist only once drawn
    return fig


def _legend_labels(fig: Figure) -> set[str]:
    legends = list(fig.legends) + [ax.get_legend() for ax in fig.axes if ax.get_legend()]
    return {t.get_text() for legend in legends for t in legend.get_texts()}


def _no_offset_text(fig: Figure) -> None:
    for ax in fig.axes:
        if ax.get_visible() and ax.axison:
            assert ax.xaxis.get_offset_text().get_text() == "", ax.get_xlabel()
            assert ax.yaxis.get_offset_text().get_text() == "", ax.get_ylabel()


def test_posterior_figures_writes_the_three_pngs(tmp_path: Path, rng: np.random.Generator) -> None:
    summary, samples, bounds = _summary(3, rng)
    paths = plots.posterior_figures(summary, samples, bounds, tmp_path, reference=centre_of(bounds))
    assert [p.name for p in paths] == [plots.FIG1_NAME, plots.FIG2_NAME, plots.PAIRS_NAME]
    for path in paths:
        image = matplotlib.image.imread(path)
        assert image.shape[0] > 200 and image.shape[1] > 200
        assert np.std(image) > 0.01  # not a blank canvas


def test_posterior_figures_with_units_band_and_verdict(
    tmp_path: Path, rng: np.random.Generator
) -> None:
    d = _dampers(rng)
    plain = plots.posterior_figures(
        d["summary"], d["draws"], d["bounds"], tmp_path / "a", d["reference"], d["units"]
    )
    full = plots.posterior_figures(
        d["summary"],
        d["draws"],
        d["bounds"],
        tmp_path / "b",
        d["reference"],
        d["units"],
        acceptable=d["acceptable"],
        reliability=NOT_TRUSTED,
    )
    for a, b in zip(plain, full):  # the band and the verdict are drawn on every figure
        assert not np.array_equal(matplotlib.image.imread(a), matplotlib.image.imread(b))


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


@pytest.mark.parametrize("plot", [plots.plot_marginals, plots.plot_pairs])
def test_transposed_or_non_finite_draws_are_refused(
    plot, tmp_path: Path, rng: np.random.Generator
) -> None:
    # (q x n) draws were reshaped to (n x q) without a word: a scrambled posterior drawn
    summary, samples, bounds = _summary(2, rng)
    with pytest.raises(ValueError, match=r"draws: shape \(2, 4000\); expected \(draws x 2\)"):
        plot(samples.T, summary, bounds, tmp_path / "x.png")
    samples[3, 1] = np.nan
    with pytest.raises(ValueError, match="draws: 1 non-finite values"):
        plot(samples, summary, bounds, tmp_path / "x.png")


def test_a_path_without_suffix_returns_the_file_written(
    tmp_path: Path, rng: np.random.Generator
) -> None:
    summary, _samples, bounds = _summary(2, rng)
    written = plots.plot_parameters(summary, bounds, tmp_path / "fig1")
    assert written == tmp_path / "fig1.png" and written.is_file()


def test_fig1_writes_physical_values_with_prefixes_and_a_full_legend(
    rng: np.random.Generator,
) -> None:
    d = _dampers(rng)
    fig = _drawn(
        plots.parameters_figure(
            d["summary"], d["bounds"], d["reference"], d["units"], acceptable=d["acceptable"]
        )
    )
    texts = [t.get_text() for t in fig.axes[0].texts]
    ticks = [t.get_text() for t in fig.axes[0].get_yticklabels()]
    plt.close(fig)
    assert any("kN·s/m" in t for t in texts) and any("MN·s/m" in t for t in texts)
    assert "C_w: 15.0–80.0 kN·s/m" in ticks[0] and "C_w: 0.50–8.00 MN·s/m" in ticks[1]
    assert any("reference 3.70" in t and "acceptable 3.90–6.50" in t for t in texts)
    assert _legend_labels(fig) == {
        plots.LABEL_ADMISSIBLE,
        plots.LABEL_INTERVAL,
        plots.LABEL_MARGINAL_MAP,
        plots.LABEL_JOINT_MAP,
        plots.LABEL_REFERENCE,
        plots.LABEL_ACCEPTABLE,
    }
    _no_offset_text(fig)


def test_fig2_zooms_to_the_posterior_mass(rng: np.random.Generator) -> None:
    d = _dampers(rng)
    fig = _drawn(
        plots.marginals_figure(
            d["draws"],
            d["summary"],
            d["bounds"],
            d["reference"],
            units=d["units"],
            acceptable=d["acceptable"],
        )
    )
    narrow, wide = fig.axes[0], fig.axes[1]
    plt.close(fig)
    assert narrow.get_xlabel().startswith("[kN·s/m]") and wide.get_xlabel().startswith("[MN·s/m]")
    lo, hi = np.array(narrow.get_xlim()) * 1e3  # back to N·s/m
    interval = d["summary"].interval95[0]
    assert lo < interval[0] and interval[1] < hi
    assert hi - lo < 0.1 * (d["bounds"][1, 0] - d["bounds"][0, 0])  # not a needle in C_w
    assert "C_w: 15.0–80.0 kN·s/m" in narrow.get_xlabel()
    # the acceptable band (32–48 kN·s/m) is beyond the narrow view: said at the edge
    assert any("acceptable 32.0–48.0 kN·s/m →" in t.get_text() for t in narrow.texts)
    assert _legend_labels(fig) >= {
        plots.LABEL_DENSITY,
        plots.LABEL_INTERVAL,
        plots.LABEL_MARGINAL_MAP,
        plots.LABEL_JOINT_MAP,
        plots.LABEL_REFERENCE,
        plots.LABEL_ACCEPTABLE,
    }
    _no_offset_text(fig)


def test_pairs_have_density_regions_units_and_a_legend(rng: np.random.Generator) -> None:
    d = _dampers(rng)
    fig = _drawn(
        plots.pairs_figure(d["draws"], d["summary"], d["bounds"], d["reference"], d["units"])
    )
    plt.close(fig)
    lower = fig.axes[2]  # row 1, column 0: the 2-D panel
    assert lower.get_xlabel().endswith("[kN·s/m]") and lower.get_ylabel().endswith("[MN·s/m]")
    assert len(lower.collections) >= 2  # filled HPD regions and their outlines
    assert _legend_labels(fig) >= {
        plots.LABEL_HPD50,
        plots.LABEL_HPD90,
        plots.LABEL_JOINT_MAP,
        plots.LABEL_REFERENCE,
        plots.LABEL_DENSITY,
    }
    _no_offset_text(fig)


@pytest.mark.parametrize(
    ("reliability", "head", "color"),
    [
        (NOT_TRUSTED, "NOT TRUSTED: budget_too_small, poor_mixing", NOT_TRUSTED_COLOR),
        (TRUSTED, "verdict: trusted", TRUSTED_COLOR),
        (None, "verdict: not computed", None),
    ],
)
def test_the_verdict_is_in_every_title(
    reliability: dict | None, head: str, color: str | None, rng: np.random.Generator
) -> None:
    d = _dampers(rng)
    args = (d["summary"], d["bounds"], d["reference"], d["units"])
    figs = [
        plots.parameters_figure(*args, reliability=reliability),
        plots.marginals_figure(d["draws"], *args[:3], units=d["units"], reliability=reliability),
        plots.pairs_figure(d["draws"], *args, reliability=reliability),
    ]
    for fig in figs:
        title = fig._suptitle
        plt.close(fig)
        assert head in title.get_text().replace("\n", " ")
        if reliability is not None:
            assert reliability["sentence"] in title.get_text().replace("\n", " ")
        if color is not None:
            assert matplotlib.colors.same_color(title.get_color(), color)


def test_verdict_title_reads_the_contract() -> None:
    assert plots.verdict_title(NOT_TRUSTED)[0] == "NOT TRUSTED: budget_too_small, poor_mixing"
    assert plots.verdict_title({"verdict": "not_trusted", "reasons": []})[0] == "NOT TRUSTED"
    assert plots.verdict_title(TRUSTED)[:2] == ("verdict: trusted", TRUSTED["sentence"])
    assert plots.verdict_title(None)[0] == "verdict: not computed"
    assert plots.verdict_title({})[0] == "verdict: not computed"


def test_hpd_levels_exact_on_a_discrete_density() -> None:
    p = np.array([[0.1, 0.4], [0.2, 0.3]])
    assert hpd_levels(p, 1.0, (0.65, 0.85, 0.3)) == [0.3, 0.2, 0.4]


def test_hpd_regions_hold_their_mass(rng: np.random.Generator) -> None:
    """The 50 % and 90 % regions hold 50 % and 90 % of the draws, on a skewed, correlated
    density with a bound in view (a swapped axis would hold almost none).

    Smoothing with Scott's bandwidth widens the density a little, which moves the held
    fraction up by about 0.02.
    """
    x = rng.gamma(2.0, 1.0, 20000)
    xy = np.column_stack([x, 3.0 * (rng.normal(size=20000) + 0.5 * x)])
    bounds = np.array([[0.0, -30.0], [30.0, 30.0]])
    unit = ((xy - bounds[0]) / (bounds[1] - bounds[0])).reshape(4, 5000, 2)
    summary = summarize(unit, bounds, ("a", "b"))
    vx = view_of(xy[:, 0], summary, 0, bounds, "m", None)
    vy = view_of(xy[:, 1], summary, 1, bounds, "m", None)
    cx, cy, p = density2d(xy[:, 0], xy[:, 1], vx, vy)
    ix = np.clip(np.searchsorted(cx, xy[:, 0]), 0, cx.size - 1)
    iy = np.clip(np.searchsorted(cy, xy[:, 1]), 0, cy.size - 1)
    for mass in (0.5, 0.9):
        (level,) = hpd_levels(p, 1.0, (mass,))
        held = np.mean(p[iy, ix] >= level)
        assert abs(held - mass) < 0.04, (mass, held)


def test_density2d_keeps_the_mass_inside_a_bound_in_view(rng: np.random.Generator) -> None:
    """Uniform draws on C_w: the smoothed density at the bounds matches the middle (reflected),
    where zero padding would halve it."""
    xy = rng.uniform(size=(20000, 2))
    bounds = np.array([[0.0, 0.0], [1.0, 1.0]])
    summary = summarize(xy.reshape(4, 5000, 2), bounds, ("a", "b"))
    vx = view_of(xy[:, 0], summary, 0, bounds, "", None)
    vy = view_of(xy[:, 1], summary, 1, bounds, "", None)
    assert vx.lo < 0.0 and vx.hi > 1.0  # both bounds in view
    _, _, p = density2d(xy[:, 0], xy[:, 1], vx, vy)
    middle = p[20:-20, 20:-20].mean()
    assert abs(p[:, 0].mean() / middle - 1.0) < 0.1
    assert abs(p[-1, :].mean() / middle - 1.0) < 0.1
    assert abs(p.sum() - 1.0) < 0.02
