"""Scores of a simulation-based calibration (SBC): coverage, z, rank uniformity, figures.

Shared by :mod:`coverage` (linearised fast path) and :mod:`coverage_pybullet` (PyBullet
data). Each experiment record holds, per parameter, the truth's posterior ``quantile``
(fraction of draws below it), ``z`` = (mean − truth)/sd and whether the 95 % interval
(``inside95``) and the equal-tailed one (``inside_equal_tailed95``) hold the truth, plus
``truth_log_l``, ``best_log_l``, ``r_hat_max``, ``check`` and ``seconds``.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
from scipy import stats


def score_draws(
    draws: np.ndarray, truth: np.ndarray, interval95: np.ndarray, equal_tailed95: np.ndarray
) -> dict[str, Any]:
    """The per-parameter fields of an experiment record.

    Args:
        draws: (n x q) posterior draws; truth: (q,) true parameters;
        interval95, equal_tailed95: (q x 2) the result's 95 % intervals.

    Returns:
        ``truth``, ``quantile``, ``z``, ``mean``, ``sd``, ``interval95``, ``inside95`` and
        ``inside_equal_tailed95``, as lists (JSON-ready).
    """
    interval = np.asarray(interval95, dtype=np.float64)
    tailed = np.asarray(equal_tailed95, dtype=np.float64)
    mean, sd = draws.mean(axis=0), draws.std(axis=0)
    return {
        "truth": truth.tolist(),
        "quantile": np.mean(draws < truth[None, :], axis=0).tolist(),
        "z": ((mean - truth) / sd).tolist(),
        "mean": mean.tolist(),
        "sd": sd.tolist(),
        "interval95": interval.tolist(),
        "inside95": ((interval[:, 0] <= truth) & (truth <= interval[:, 1])).tolist(),
        "inside_equal_tailed95": ((tailed[:, 0] <= truth) & (truth <= tailed[:, 1])).tolist(),
    }


def _binomial_range(n: int, p: float = 0.95) -> tuple[int, int]:
    lo, hi = stats.binom.interval(0.95, n, p)
    return int(lo), int(hi)


def aggregate(records: list[dict[str, Any]], names: tuple[str, ...]) -> dict[str, Any]:
    """Every figure of the report from the experiment records."""
    quantiles = np.array([r["quantile"] for r in records])
    z = np.array([r["z"] for r in records])
    inside = np.array([r["inside95"] for r in records])
    tailed = np.array([r["inside_equal_tailed95"] for r in records])
    n = len(records)
    lo, hi = _binomial_range(n)
    pooled_lo, pooled_hi = _binomial_range(inside.size)
    gap = np.array([r["truth_log_l"] - r["best_log_l"] for r in records])
    per = {}
    for k, name in enumerate(names):
        per[name] = {
            "ks_p": float(stats.kstest(quantiles[:, k], "uniform").pvalue),
            "z_rms": float(np.sqrt(np.mean(z[:, k] ** 2))),
            "z_mean": float(np.mean(z[:, k])),
            "inside95": int(inside[:, k].sum()),
            "inside_equal_tailed95": int(tailed[:, k].sum()),
            "binomial_range": [lo, hi],
            "coverage_ok": bool(lo <= inside[:, k].sum() <= hi),
            "quantile_in_middle_half": float(
                np.mean((quantiles[:, k] >= 0.25) & (quantiles[:, k] <= 0.75))
            ),
        }
    laplace = None
    if all("laplace" in r for r in records):
        lq = np.array([r["laplace"]["quantile"] for r in records])
        lz = np.array([r["laplace"]["z"] for r in records])
        li = np.array([r["laplace"]["inside95"] for r in records])
        laplace = {
            "pooled": {
                "ks_p": float(stats.kstest(lq.ravel(), "uniform").pvalue),
                "z_rms": float(np.sqrt(np.mean(lz**2))),
                "inside95": int(li.sum()),
                "of": int(li.size),
                "binomial_range": [pooled_lo, pooled_hi],
            },
            "per_parameter": {
                name: {
                    "ks_p": float(stats.kstest(lq[:, k], "uniform").pvalue),
                    "z_rms": float(np.sqrt(np.mean(lz[:, k] ** 2))),
                    "inside95": int(li[:, k].sum()),
                    "binomial_range": [lo, hi],
                }
                for k, name in enumerate(names)
            },
            "sd_fraction_of_range_median": np.median(
                [r["laplace"]["sd_fraction_of_range"] for r in records], axis=0
            ).tolist(),
            "surrogate_sd_over_laplace_sd_median": np.median(
                [np.divide(r["sd"], r["laplace"]["sd"]) for r in records], axis=0
            ).tolist(),
        }
    return {
        "n_experiments": n,
        "exact_likelihood_laplace": laplace,
        "pooled": {
            "ks_p": float(stats.kstest(quantiles.ravel(), "uniform").pvalue),
            "z_rms": float(np.sqrt(np.mean(z**2))),
            "inside95": int(inside.sum()),
            "of": int(inside.size),
            "binomial_range": [pooled_lo, pooled_hi],
            "quantile_in_middle_half": float(np.mean((quantiles >= 0.25) & (quantiles <= 0.75))),
        },
        "per_parameter": per,
        "search": {
            # "optimum not reached": best evaluated log L below the log L expected at the
            # truth under B by more than 3 sd (likelihood.expected_log_likelihood_at_truth)
            "best_below_expected_at_truth_by_3sd": int(
                sum(
                    r["best_log_l"]
                    < r["expected_log_l_at_truth"][0] - 3 * r["expected_log_l_at_truth"][1]
                    for r in records
                    if "expected_log_l_at_truth" in r
                    and math.isfinite(r["expected_log_l_at_truth"][0])
                )
            ),
            "best_minus_expected_at_truth_in_sd": [
                (r["best_log_l"] - r["expected_log_l_at_truth"][0])
                / r["expected_log_l_at_truth"][1]
                for r in records
                if "expected_log_l_at_truth" in r and math.isfinite(r["expected_log_l_at_truth"][0])
            ],
            "truth_beats_best_evaluated": int(np.sum(gap > 0)),
            "truth_minus_best_log_l_median": float(np.median(gap)),
            "truth_minus_best_log_l_max": float(np.max(gap)),
        },
        "r_hat_max": float(max(r["r_hat_max"] for r in records)),
        "checks": {v: sum(r["check"] == v for r in records) for v in {r["check"] for r in records}},
        "seconds_per_experiment_median": float(np.median([r["seconds"] for r in records])),
    }


def rank_figure(
    records: list[dict[str, Any]], names: tuple[str, ...], path: Path, source: str = ""
) -> None:
    """Histograms of the truth's posterior quantile per parameter and pooled (PNG);
    ``source`` names the data in the title (e.g. "PyBullet data")."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    quantiles = np.array([r["quantile"] for r in records])
    n = len(records)
    bins = max(4, min(10, n // 4))
    panels = [*names, "pooled"]
    cols = 4
    rows = math.ceil(len(panels) / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 2.6 * rows), squeeze=False)
    overlay = None
    if all("laplace" in r for r in records) and not any(r.get("reference_only") for r in records):
        overlay = np.array([r["laplace"]["quantile"] for r in records])
    for ax, name in zip(axes.ravel(), panels):
        data = quantiles.ravel() if name == "pooled" else quantiles[:, names.index(name)]
        ax.hist(data, bins=bins, range=(0, 1), color="tab:blue", edgecolor="white")
        if overlay is not None:
            ref = overlay.ravel() if name == "pooled" else overlay[:, names.index(name)]
            ax.hist(
                ref,
                bins=bins,
                range=(0, 1),
                histtype="step",
                color="k",
                lw=1.5,
                label="exact-likelihood Laplace",
            )
            if name == "pooled":
                ax.legend(fontsize=6, loc="upper center")
        expect = data.size / bins
        band = stats.binom.interval(0.95, data.size, 1 / bins)
        ax.axhline(expect, color="k", lw=1)
        ax.axhspan(band[0], band[1], color="0.85", zorder=0)
        for edge in band:  # dashed over the bars: a bar short of the lower edge shows
            ax.axhline(edge, color="0.35", ls="--", lw=0.9, zorder=3)
        p = stats.kstest(data, "uniform").pvalue
        ax.set_title(f"{name}\nKS p = {p:.2g}", fontsize=8)
        ax.set_xlim(0, 1)
        ax.tick_params(labelsize=7)
        ax.set_xlabel("truth's posterior quantile", fontsize=7)
        ax.set_ylabel("experiments" if name != "pooled" else "parameters x experiments",
                      fontsize=7)  # fmt: skip
    for ax in axes.ravel()[len(panels) :]:
        ax.axis("off")
    kind = (
        "exact-likelihood Laplace posterior"
        if records[0].get("reference_only")
        else "calibrate loop; black: exact-likelihood Laplace"
        if overlay is not None
        else "calibrate loop"
    )
    fig.suptitle(
        f"SBC rank histograms: truth's posterior quantile, {n} experiments "
        f"({kind}{'; ' + source if source else ''};\n"
        "grey, dashed edges: 95 % range of one bin's count under uniform ranks)",
        fontsize=9,
    )
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
