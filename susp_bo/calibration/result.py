"""What :func:`susp_bo.calibration.loop.calibrate` returns: the result and its iteration reports."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from susp_bo.calibration.basin_search import ClimbReport
from susp_bo.calibration.design import from_unit
from susp_bo.calibration.local_search import LocalSearchResult
from susp_bo.calibration.posterior import PosteriorSummary
from susp_bo.calibration.reliability import Reliability
from susp_bo.calibration.surrogate import Surrogate
from susp_bo.calibration.surrogate_check import SurrogateCheck

Phase = Literal["design", "ego", "basin", "local", "refine", "explore", "check"]


@dataclass(frozen=True)
class KernelSwitch:
    """The comparisons a run made and whether it switched.

    Attributes:
        checks: ((n_evaluations, gain in nats a point), …) in the order they were made.
        switched_at: evaluations when the run switched to ``kernel="auto"``; None = never.
    """

    checks: tuple[tuple[int, float], ...]
    switched_at: int | None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: ``checks`` as [{"n_evaluations", "additive_kernel_loo_gain"}, …]
        (the gain null where the additive fit failed)."""
        return {
            "checks": [
                {
                    "n_evaluations": n,
                    "additive_kernel_loo_gain": gain if math.isfinite(gain) else None,
                }
                for n, gain in self.checks
            ],
            "switched_at": self.switched_at,
        }


@dataclass(frozen=True)
class IterationReport:
    """One refinement iteration, passed to ``on_iteration`` and logged as one line."""

    iteration: int
    phase: Phase
    n_evaluations: int
    best_log_likelihood: float
    best_parameters: np.ndarray
    criterion: float
    n_failed: int

    def criterion_text(self) -> str:
        """The phase's stopping statistic, named: e.g. ``"EI/spread 0.0795"``.

        The local phase's finite-difference batches predict no gain (NaN): they are
        named as such, not printed as ``nan``.
        """
        name = {
            "ego": "EI/spread",
            "check": "max |check error| (nats)",
            "local": "predicted gain (nats)",
            "basin": "basin best log L",
            "explore": "audit: max log L above prediction (nats)",
        }.get(self.phase, "posterior sd of log L (nats)")
        if math.isfinite(self.criterion):
            return f"{name} {self.criterion:.3g}"
        if self.phase == "local":
            return "finite-difference runs (no gain predicted)"
        return f"{name} n/a"

    def line(self) -> str:
        """One-line summary."""
        return (
            f"iter {self.iteration:3d} [{self.phase}] evaluations {self.n_evaluations}"
            f" best log L {self.best_log_likelihood:.6g} {self.criterion_text()}"
            f" failed {self.n_failed}"
        )


@dataclass(frozen=True)
class CalibrationResult:
    """Result of :func:`calibrate`.

    Attributes:
        names: (q,) parameter names.
        bounds: (2 x q) bounds of C_w.
        X: (n x q) evaluated parameters, physical units, in evaluation order.
        y: (n,) log L values as returned (NaN = failed).
        surrogate: the final fitted surrogate (unit-cube inputs).
        draws: (n_chains x n_draws x q) posterior draws, physical units.
        summary: posterior summary (physical units).
        n_evaluations: number of log L evaluations.
        stop_reason: "budget", "converged" or "ego_converged" (no refinement).
        history: one report per refinement iteration.
        mcmc: kernel diagnostics of the final run (acceptance rate, scale or step size,
            the sampler whose draws these are: ``random_walk`` or ``hmc``).
        check: the held-out check of the surrogate posterior (None when
            ``check_points`` is 0 or no budget was left for it).
        reliability: the verdict on this result (:mod:`.reliability`).
        search_box: (2 x q) the final search box (physical units) the surrogate, the
            check points and the MCMC worked in: C_w itself unless
            ``settings.trust_region`` or the local phase set a box (:mod:`.trust_region`).
        local_search: what the local phase found (mode and Laplace covariance in the unit
            cube of C_w), None when it did not run (:mod:`.local_search`).
        local_search_superseded: True when an early stop's audit
            (:mod:`.exploration_audit`) found posterior mass after the local phase: the
            search then went on over C_w, and ``local_search`` describes the first hill only.
        basins: the climbs of the basin phase (:mod:`.basin_search`), empty when the data
            had no secondary basin when EGO ended (or the phase is off).
        kernel_switch: the leave-one-out comparisons of the additive kernel with the
            Matérn during the search and when the run switched to ``kernel="auto"``
            (:mod:`.kernel_switch`); None when none was made (``result.json`` then has no
            ``kernel_switch`` key).
        modes_optimism_at: the evaluations when the basin phase's count of two or more
            confirmed peaks raised the refinement's ``refine_optimism`` to
            ``CalibrationSettings.modes_refine_optimism``; None when it did not
            (``result.json`` then has no ``modes_refine_optimism_from_evaluation`` key).
    """

    names: tuple[str, ...]
    bounds: np.ndarray
    X: np.ndarray
    y: np.ndarray
    surrogate: Surrogate
    draws: np.ndarray
    summary: PosteriorSummary
    n_evaluations: int
    stop_reason: str
    history: tuple[IterationReport, ...]
    mcmc: dict[str, float | str]
    check: SurrogateCheck | None = None
    reliability: Reliability | None = None
    search_box: np.ndarray | None = None
    local_search: LocalSearchResult | None = None
    basins: tuple[ClimbReport, ...] = ()
    local_search_superseded: bool = False
    kernel_switch: KernelSwitch | None = None
    modes_optimism_at: int | None = None

    @property
    def samples(self) -> np.ndarray:
        """Posterior draws pooled over chains, (draws x q), physical units."""
        return self.draws.reshape(-1, self.draws.shape[-1])

    @property
    def box(self) -> np.ndarray:
        """(2 x q) the box the surrogate works in (its unit cube): the search box or C_w."""
        return self.bounds if self.search_box is None else self.search_box

    def basin_climbs(self) -> list[dict[str, Any]]:
        """The basin phase's climbs, JSON-ready (start and end in physical units)."""
        return [
            {
                "start": from_unit(c.start[None], self.bounds)[0].tolist(),
                "end": from_unit(c.end[None], self.bounds)[0].tolist(),
                "start_log_likelihood": c.start_log_likelihood,
                "end_log_likelihood": c.end_log_likelihood,
                "n_evaluations": c.n_evaluations,
                "stop_reason": c.stop_reason,
            }
            for c in self.basins
        ]

    def local_search_dict(self) -> dict[str, Any] | None:
        """The local phase, JSON-ready: mode, Laplace sd (physical units), stop, and
        ``superseded_by_audit`` when an audit found mass after it; or None."""
        local = self.local_search
        if local is None:
            return None
        span = self.bounds[1] - self.bounds[0]
        return {
            "mode": (self.bounds[0] + local.mode * span).tolist(),
            "laplace_sd": (local.sd * span).tolist(),
            "log_likelihood": local.log_likelihood,
            "n_evaluations": local.n_evaluations,
            "stop_reason": local.stop_reason,
            "iterations": local.iterations,
        } | (  # the key only when it happened: results of runs without it are unchanged
            {"superseded_by_audit": True} if self.local_search_superseded else {}
        )

    def to_dict(self) -> dict[str, Any]:
        """The calibration's part of ``result.json``: the same keys, layout and meaning.

        Physical units; ``bounds`` as (q x 2) pairs (lower, upper), r-hat and ESS under
        ``mcmc``. ``result.json`` adds the study's context (units, rig, data, reference,
        output error, number of simulations, version, …).
        """
        summary = self.summary.to_dict()
        return (
            {
                "parameters": list(self.names),
                "bounds": [[float(lo), float(hi)] for lo, hi in self.bounds.T],
                "joint_map": summary["joint_map"],
                "marginal_map": summary["marginal_map"],
                "interval95": summary["interval95"],
                "equal_tailed95": summary["equal_tailed95"],
                "posterior_mean": summary["mean"],
                "posterior_sd": summary["sd"],
                "n_evaluations": int(self.n_evaluations),
                "n_failed_evaluations": int(np.sum(~np.isfinite(self.y))),
                "stop_reason": self.stop_reason,
                "best_log_likelihood": float(np.nanmax(self.y)),
                "mcmc": {"r_hat": summary["r_hat"], "ess": summary["ess"], **self.mcmc},
                "surrogate_check": None if self.check is None else self.check.to_dict(self.box),
                "search_box": None if self.search_box is None else self.search_box.tolist(),
                "local_search": self.local_search_dict(),
                "basin_climbs": self.basin_climbs(),
                "reliability": None if self.reliability is None else self.reliability.to_dict(),
            }
            | (  # the key only where the kernels were compared: other results are unchanged
                {}
                if self.kernel_switch is None
                else {"kernel_switch": self.kernel_switch.to_dict()}
            )
            | (  # the key only where several modes raised the refinement's optimism
                {}
                if self.modes_optimism_at is None
                else {"modes_refine_optimism_from_evaluation": self.modes_optimism_at}
            )
        )
