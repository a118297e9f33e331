"""Secondary basins of log L: a local climb from evaluated points that head other modes.

EGO (qLogEI) spends its evaluations where the *global* maximum may still improve, so
a second mode whose peak is a few nats below the first is found only by chance, at its
fringe, and then left behind: the surrogate extrapolates downward from the fringe, the
surrogate posterior puts no draws there, and the refinement (which picks among those
draws) never goes there either. Measured on the trimodal 5-D target
(``benchmarks/posterior_accuracy.py``, seed 1, 350 evaluations): the third mode (20 % of
the mass) had 3 evaluations at Mahalanobis² 20–50 from its centre and none nearer; the
surrogate was 35 nats too low over its bulk and the posterior draws gave it 0 % of the
mass (MMTV 0.19).

When EGO ends, :func:`secondary_basins` lets every evaluated point within ``depth`` nats
of the best climb the surrogate's mean by gradient ascent; the climbs that end away
from the best point's (more than ``radius``, Chebyshev distance in the unit cube of C_w)
mark other basins of the surrogate, each headed by its best evaluated point. From each,
the one whose top may be highest first, :func:`climb` runs a TuRBO-like local search: a
qLogEI batch with the basin's own best value as the incumbent, optimised in a box of
half-width h around the basin's best point; h doubles (up to ``max_half_width``) after a
batch that improved on it by more than ``improvement`` nats and halves after one that did
not. A climb ends when h falls below ``min_half_width``, when the basin merges into
another one (its best point comes within ``radius`` of the top of a basin known already),
or when its share of the phase's budget is spent (:func:`basin_phase`). A unimodal log L
whose surrogate has a single basin among those points (the usual case) costs one gradient
ascent and changes nothing else.

With ``hunt_beta`` > 0 (3, the default since session 43), where the surrogate has two or
more peaks confirmed by evaluations when the phase starts, the phase also hunts for modes no
evaluation came near (:mod:`.mode_hunt`, session 41), until a hunt batch finds nothing.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch

from susp_bo.calibration.acquisition import propose_ei_batch
from susp_bo.calibration.cube_ascent import chebyshev, projected_ascent
from susp_bo.calibration.mode_hunt import CONFIRM_GAIN, hunt_batch, surrogate_peaks
from susp_bo.calibration.surrogate import Surrogate
from susp_bo.calibration.trust_region import posterior_reach


@dataclass(frozen=True)
class BasinSettings:
    """Settings of the basin phase (unit-cube lengths, log L in nats).

    Args:
        radius: surrogate maxima closer than this (Chebyshev, unit cube) are one basin; a
            climb whose best point comes this close to a higher point it did not find has
            merged into that point's basin; in (0, 1).
        depth: only basins whose best value is within this many nats of the best point
            are climbed (> 0).
        initial_half_width: half-width of the first climbing box, unit cube, in (0, 0.5].
        min_half_width: a climb ends when the box is narrower than this (> 0).
        max_half_width: the box never grows beyond this (>= initial_half_width).
        improvement: a batch improved on the basin's best when it beat it by more than
            this many nats (>= 0).
        max_basins: most basins climbed (>= 1).
        budget_fraction: share of the evaluations left when EGO ends that the phase may
            use, in (0, 1); shared equally between the basins found (a climb's share is
            what is left over the number of basins still to climb).
        hunt_beta: where the surrogate's mean has two or more peaks when the phase starts,
            each confirmed by an evaluation within 2 nats of its top
            (:func:`.mode_hunt.surrogate_peaks`), one batch first goes to the local maxima
            of mean + ``hunt_beta`` sd (:mod:`.mode_hunt`), and again after each such
            batch (and after each climb) while the surrogate still has two such peaks, a
            maximum of that bound away from the known modes reaches the posterior and no
            batch came back with nothing within the posterior's reach of the best; 0 turns
            that off (>= 0). Default 3, the measured setting (:mod:`.mode_hunt`: it keeps
            the modes a trimodal target lost; session 43). ``calibrate`` runs it only in a
            search over C_w with a fixed noise
            (:meth:`.settings.CalibrationSettings.global_fixed_noise_search`).
        hunt_fraction: share of the phase's evaluations those batches may use, in (0, 1]
            (climbs may use them too; the hunts' own count is kept apart).
    """

    radius: float = 0.1
    depth: float = 20.0
    initial_half_width: float = 0.05
    min_half_width: float = 0.02
    max_half_width: float = 0.2
    improvement: float = 1.0
    max_basins: int = 4
    budget_fraction: float = 0.4
    hunt_beta: float = 3.0
    hunt_fraction: float = 0.5

    def __post_init__(self) -> None:
        if not 0.0 < self.radius < 1.0:
            raise ValueError(f"basin radius: {self.radius} must be in (0, 1)")
        if not self.depth > 0.0:
            raise ValueError(f"basin depth: {self.depth} must be > 0 nats")
        if not 0.0 < self.initial_half_width <= 0.5:
            raise ValueError(
                f"basin initial_half_width: {self.initial_half_width} must be in (0, 0.5]"
            )
        if not 0.0 < self.min_half_width <= self.initial_half_width <= self.max_half_width:
            raise ValueError(
                "basin half-widths: need 0 < min_half_width <= initial_half_width <= "
                f"max_half_width, got {self.min_half_width}, {self.initial_half_width}, "
                f"{self.max_half_width}"
            )
        if not self.improvement >= 0.0:
            raise ValueError(f"basin improvement: {self.improvement} must be >= 0 nats")
        if int(self.max_basins) != self.max_basins or self.max_basins < 1:
            raise ValueError(f"basin max_basins: {self.max_basins} must be an integer >= 1")
        if not 0.0 < self.budget_fraction < 1.0:
            raise ValueError(f"basin budget_fraction: {self.budget_fraction} must be in (0, 1)")
        if not self.hunt_beta >= 0.0:
            raise ValueError(f"basin hunt_beta: {self.hunt_beta} must be >= 0 (0: no hunt)")
        if not 0.0 < self.hunt_fraction <= 1.0:
            raise ValueError(f"basin hunt_fraction: {self.hunt_fraction} must be in (0, 1]")


def surrogate_ascent(surrogate: Surrogate, u: np.ndarray, steps: int = 300) -> np.ndarray:
    """Where gradient ascent on the surrogate's latent mean takes each start (unit cube).

    Args:
        surrogate: the fitted surrogate.
        u: (n x q) starts in the unit cube.
        steps: Adam steps (learning rate 0.01 unit-cube lengths; projected on the cube).

    Returns:
        (n x q) end points: the surrogate's local maxima the starts lead to.
    """
    return projected_ascent(surrogate.latent_mean, u, steps)


def _peaked(surrogate: Surrogate, ends: np.ndarray, step: float, drop: float) -> np.ndarray:
    """(n,) whether the surrogate's log L falls by ``drop`` at ``step`` along every axis."""
    n, q = ends.shape
    offsets = np.concatenate([np.eye(q), -np.eye(q)]) * step  # 2q x q
    around = np.clip(ends[:, None, :] + offsets[None], 0.0, 1.0)  # n x 2q x q
    moved = np.any(np.abs(around - ends[:, None, :]) > 0.0, axis=-1)  # on the cube's face: no
    with torch.no_grad():
        centre = surrogate.log_likelihood_mean(torch.as_tensor(ends)).numpy()
        values = surrogate.log_likelihood_mean(torch.as_tensor(around.reshape(-1, q))).numpy()
    falls = values.reshape(n, 2 * q) < centre[:, None] - drop
    return np.all(falls | ~moved, axis=1)


def ascent_ends(
    x_unit: np.ndarray,
    y: np.ndarray,
    surrogate: Surrogate,
    radius: float,
    depth: float,
    min_drop: float = 0.5,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where the evaluated points within ``depth`` nats of the best climb the surrogate to.

    Returns:
        The indices of those points (m,), best first; the ends of their ascents on the
        surrogate's mean (m x q, :func:`surrogate_ascent`); and whether each end is a peak
        (m,): the surrogate's log L falls by ``min_drop`` nats ``radius`` away along every
        axis. Deterministic: no random draw.
    """
    finite = np.flatnonzero(np.isfinite(y))
    keep = finite[y[finite] >= np.max(y[finite]) - depth]
    keep = keep[np.argsort(-y[keep], kind="stable")]  # best first
    ends = surrogate_ascent(surrogate, x_unit[keep])
    return keep, ends, _peaked(surrogate, ends, radius, min_drop)


def secondary_basins(
    x_unit: np.ndarray,
    y: np.ndarray,
    surrogate: Surrogate,
    radius: float,
    depth: float,
    exclude: np.ndarray | None = None,
    min_drop: float = 0.5,
    min_gain: float = 2.0,
    ascent: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
) -> list[int]:
    """Evaluated points heading basins of the surrogate other than the best point's.

    Every evaluated point within ``depth`` nats of the best climbs the surrogate's mean
    (:func:`surrogate_ascent`); points whose climbs end within ``radius`` of each other
    share a basin. Basins whose end lies within ``radius`` of the best point's end or of
    an ``exclude`` point, or whose head does, are dropped, and so are ends that are not a
    peak of the surrogate's log L (it must fall by ``min_drop`` nats ``radius`` away
    along every axis: a climb that stalled where the GP mean is flat, far from the data,
    is not a basin), and so are basins whose top is evaluated already (``min_gain``).

    Args:
        x_unit: (n x q) evaluated points in the unit cube.
        y: (n,) their log L (NaN = failed, ignored).
        surrogate: the surrogate fitted on these data (unit cube of the same box).
        radius: basin radius (Chebyshev distance, unit cube).
        depth: keep points within this many nats of the best.
        exclude: (m x q) unit-cube points of basins already explored.
        min_drop: nats the surrogate's log L must fall around a basin's end (>= 0).
        min_gain: a basin whose top may not beat its best evaluated point by this many
            nats (the surrogate's mean + 2 sd at the end) is explored already.
        ascent: :func:`ascent_ends` of these data and surrogate, if computed already.

    Returns:
        The best evaluated point of each remaining basin (indices), the basin whose top
        may be highest (mean + 2 sd at its end) first.
    """
    y = np.asarray(y, dtype=np.float64)
    if np.isfinite(y).sum() < 2:
        return []
    keep, ends, peaked = (
        ascent_ends(x_unit, y, surrogate, radius, depth, min_drop) if ascent is None else ascent
    )
    explored = ends[:1] if exclude is None or len(exclude) == 0 else np.vstack([ends[:1], exclude])
    done = np.empty((0, x_unit.shape[1])) if exclude is None else np.asarray(exclude)
    with torch.no_grad():
        mean, sd = surrogate.log_likelihood_uncertainty(torch.as_tensor(ends))
    upper = (mean + 2.0 * sd).numpy()
    heads: list[tuple[float, int]] = []
    for i in range(1, len(keep)):
        if np.any(chebyshev(ends[i][None], explored)[0] < radius):
            continue  # a basin seen already (from a higher point: points come best first)
        explored = np.vstack([explored, ends[i][None]])
        if len(done) and np.any(chebyshev(x_unit[keep[i]][None], done)[0] < radius):
            continue
        if upper[i] < y[keep[i]] + min_gain:
            continue  # its top is evaluated already
        if not peaked[i]:
            continue  # a flat stretch of the surrogate, not a maximum
        heads.append((float(upper[i]), int(keep[i])))
    return [i for _, i in sorted(heads, key=lambda item: -item[0])]


@dataclass(frozen=True)
class ClimbReport:
    """What one climb did: where it started and ended (unit cube), its values and why it ended."""

    start: np.ndarray
    end: np.ndarray
    start_log_likelihood: float
    end_log_likelihood: float
    n_evaluations: int
    stop_reason: str  # "narrow", "merged" or "budget"; "hunt": the batch of .mode_hunt


def climb(
    x_unit: np.ndarray,
    y: np.ndarray,
    start: int,
    budget: int,
    batch_size: int,
    settings: BasinSettings,
    fit: Callable[[np.ndarray, np.ndarray], Surrogate],
    evaluate: Callable[[np.ndarray], np.ndarray],
    seed: Callable[[], int],
    restarts: int,
    raw_samples: int,
    known: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, ClimbReport]:
    """Local qLogEI climb from evaluated point ``start`` (module docstring).

    Args:
        x_unit: (n x q) evaluated points, unit cube; y: (n,) their log L.
        start: index of the basin's best point.
        budget: most evaluations the climb may use (>= 1).
        batch_size: points per batch.
        settings: the basin settings.
        fit: (x_unit, y) -> the surrogate fitted on those data.
        evaluate: (b x q) unit-cube points -> (b,) log L (NaN = failed); each call is a batch.
        seed: () -> seed of the next batch's acquisition.
        restarts, raw_samples: qLogEI optimisation settings.
        known: (m x q) unit-cube tops of the basins known already (the best point, earlier
            climbs' ends): a climb whose best point comes within ``radius`` of one has
            merged into that basin and ends.

    Returns:
        (x_unit, y) with the climb's evaluations appended, and its report.
    """
    q = x_unit.shape[1]
    best = start
    half = settings.initial_half_width
    used, reason = 0, "budget"
    while used < budget:
        if half < settings.min_half_width:
            reason = "narrow"
            break
        if len(known) and np.any(chebyshev(x_unit[best][None], known)[0] < settings.radius):
            reason = "merged"
            break
        surrogate = fit(x_unit, y)
        centre = torch.as_tensor(x_unit[best], dtype=torch.float64)
        box = torch.stack([(centre - half).clamp(0.0, 1.0), (centre + half).clamp(0.0, 1.0)])
        size = min(batch_size, budget - used)
        incumbent = float(surrogate.warping.forward(np.array([y[best]]))[0])
        u, _ = propose_ei_batch(
            surrogate, size, seed(), restarts, raw_samples, box=box, best_f=incumbent
        )
        new_x = u.numpy().reshape(-1, q)
        new_y = np.asarray(evaluate(new_x), dtype=np.float64).reshape(-1)
        x_unit, y = np.vstack([x_unit, new_x]), np.concatenate([y, new_y])
        used += len(new_y)
        finite_new = np.isfinite(new_y)
        top = float(np.max(new_y[finite_new])) if finite_new.any() else -math.inf
        gain = top - y[best]
        if gain > 0.0:
            best = x_unit.shape[0] - len(new_y) + int(np.nanargmax(new_y))
        if gain > settings.improvement:
            half = min(2.0 * half, settings.max_half_width)
        else:
            half /= 2.0
    report = ClimbReport(
        start=x_unit[start].copy(),
        end=x_unit[best].copy(),
        start_log_likelihood=float(y[start]),
        end_log_likelihood=float(y[best]),
        n_evaluations=used,
        stop_reason=reason,
    )
    return x_unit, y, report


@dataclass(frozen=True)
class BasinPhase:
    """What the basin phase did.

    Attributes:
        climbs: one report per climb or hunt batch, in order (empty: nothing to climb).
        confirmed_peaks: the most peaks of the surrogate's mean, each confirmed by an
            evaluation within :data:`.mode_hunt.CONFIRM_GAIN` nats of its top, counted at
            the start of any round (:func:`confirmed_peaks`): 2 or more means the search
            has met several modes of log L.
    """

    climbs: list[ClimbReport]
    confirmed_peaks: int


def confirmed_peaks(
    x_unit: np.ndarray, y: np.ndarray, surrogate: Surrogate, settings: BasinSettings
) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """The surrogate's peaks that an evaluation confirms, and the ascent that found them.

    Args:
        x_unit: (n x q) evaluated points, unit cube; y: (n,) their log L.
        surrogate: fitted on them.
        settings: the basin settings (``radius``, ``depth``).

    Returns:
        ((k x q) the confirmed peaks, unit cube; the :func:`ascent_ends` of these data,
        for :func:`secondary_basins` on the same surrogate).
    """
    ascent = ascent_ends(x_unit, y, surrogate, settings.radius, settings.depth)
    keep, ends, peaked = ascent
    with torch.no_grad():
        tops = surrogate.log_likelihood_mean(torch.as_tensor(ends)).numpy()
    peaks = surrogate_peaks(ends, peaked, settings.radius, tops <= y[keep] + CONFIRM_GAIN)
    return peaks, ascent


def basin_phase(
    x_unit: np.ndarray,
    y: np.ndarray,
    budget: int,
    batch_size: int,
    settings: BasinSettings,
    fit: Callable[[np.ndarray, np.ndarray], Surrogate],
    evaluate: Callable[[np.ndarray], np.ndarray],
    seed: Callable[[], int],
    restarts: int,
    raw_samples: int,
) -> BasinPhase:
    """The whole phase: find secondary basins, climb the most promising, repeat.

    Each round refits the surrogate on all data, lists the basins not explored yet
    (:func:`secondary_basins`) and climbs the first (:func:`climb`) with an equal share of
    the budget left among the basins still to climb; its start and end are then explored.
    Before each round (the first, and after each climb, which may have confirmed a second
    mode), while the surrogate's mean has two or more confirmed peaks among the points
    within ``settings.depth`` (:func:`.mode_hunt.surrogate_peaks`), ``settings.hunt_beta``
    > 0 and ``settings.hunt_fraction`` of ``budget`` is not spent, batches go where a mode
    may hide (:func:`.mode_hunt.hunt_batch`), one per refit; each is reported as a climb
    with ``stop_reason`` "hunt" (start: the best point; end: the batch's best point). The
    hunt needs two confirmed peaks in the first round (when the global search ended: peaks
    that only climbs confirm are the ends of a ridge they followed, as on a curved
    posterior), and ends for the phase at the first batch whose best point falls below the
    posterior's reach of the best value (:func:`.trust_region.posterior_reach`), or has no
    finite value: the upper bounds it followed were empty. With one confirmed peak in the
    first round, the phase is what it was without the hunt, bit for bit.

    Args:
        x_unit: (n x q) evaluated points, unit cube of C_w; y: (n,) their log L.
        budget: evaluations the phase may use.
        batch_size: points per batch.
        settings: the basin settings.
        fit, evaluate, seed, restarts, raw_samples: as for :func:`climb` (``evaluate``
            records each batch with the caller).

    Returns:
        One report per climb (empty when the data head no secondary basin), and the most
        confirmed peaks counted at the start of a round.
    """
    explored = np.empty((0, x_unit.shape[1]))
    most_peaks = 0
    climbs: list[ClimbReport] = []
    used = 0
    hunting = settings.hunt_beta > 0.0
    hunt_over = False  # no hunt for the rest of the phase: one peak at first, or a fruitless batch
    hunt_left = int(settings.hunt_fraction * budget)  # the hunts' share; climbs do not use it up
    climbed = 0
    while used < budget and climbed < settings.max_basins:
        surrogate = fit(x_unit, y)
        ascent = None
        peaks = np.empty((0, x_unit.shape[1]))
        if np.isfinite(y).sum() >= 2:  # the same ascent serves the hunt and the detection
            peaks, ascent = confirmed_peaks(x_unit, np.asarray(y, dtype=np.float64), surrogate,
                                            settings)  # fmt: skip
            most_peaks = max(most_peaks, len(peaks))
        if not climbs and len(peaks) < 2:
            # one mode when the global search ended: peaks that climbs confirm later are the
            # ends of a ridge they followed (a curved posterior), not modes it missed
            hunt_over = True
            hunting = False
        if hunting:
            size = min(hunt_left, budget - used)
            ends = ascent[1] if ascent is not None else peaks
            x_unit, y, hunt = _hunt(x_unit, y, surrogate, size, batch_size, settings, evaluate,
                                    seed, peaks, ends)  # fmt: skip
            if hunt is not None:
                used += hunt.n_evaluations
                hunt_left -= hunt.n_evaluations
                climbs.append(hunt)
                # a batch with no point within the posterior's reach of the best found no
                # mode: the upper bounds it followed were empty, the rest would be lower
                fruitless = not hunt.end_log_likelihood >= (
                    hunt.start_log_likelihood - posterior_reach(x_unit.shape[1])
                )
                hunt_over = hunt_over or fruitless
                hunting = not hunt_over
                continue  # refit with the hunt's evaluations; hunt again, or detect basins
            hunting = False
        found = secondary_basins(
            x_unit, y, surrogate, settings.radius, settings.depth, explored, ascent=ascent
        )
        if not found:
            break
        share = max(1, min(len(found), settings.max_basins - climbed))
        known = np.vstack([x_unit[int(np.nanargmax(y))][None], explored])
        x_unit, y, report = climb(
            x_unit,
            y,
            found[0],
            min(budget - used, max(batch_size, (budget - used) // share)),
            batch_size,
            settings,
            fit,
            evaluate,
            seed,
            restarts,
            raw_samples,
            known,
        )
        used += report.n_evaluations
        explored = np.vstack([explored, report.start[None], report.end[None]])
        climbs.append(report)
        climbed += 1
        hunting = settings.hunt_beta > 0.0 and not hunt_over  # a climb may confirm a mode
    return BasinPhase(climbs, most_peaks)


def _hunt(
    x_unit: np.ndarray,
    y: np.ndarray,
    surrogate: Surrogate,
    budget: int,
    batch_size: int,
    settings: BasinSettings,
    evaluate: Callable[[np.ndarray], np.ndarray],
    seed: Callable[[], int],
    peaks: np.ndarray,
    ends: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, ClimbReport | None]:
    """The hunt batch of :mod:`.mode_hunt` where the surrogate has two confirmed peaks or more.

    Args:
        peaks: (k x q) the surrogate's confirmed peaks (:func:`confirmed_peaks`).
        ends: where the evaluated points climb to on ``surrogate`` (:func:`ascent_ends`):
            the modes known already.

    Returns:
        (x_unit, y) with the hunt's evaluations appended, and its report (None, and the
        data unchanged, where the surrogate has one peak or no upper bound reaches).
    """
    y = np.asarray(y, dtype=np.float64)
    if budget < 1 or len(peaks) < 2:
        return x_unit, y, None
    best = int(np.nanargmax(y))
    q = x_unit.shape[1]
    new_x = hunt_batch(
        surrogate,
        float(y[best]),
        posterior_reach(q),
        min(batch_size, budget),
        settings.radius,
        settings.hunt_beta,
        seed(),
        ends,
    )
    if not len(new_x):
        return x_unit, y, None
    new_y = np.asarray(evaluate(new_x), dtype=np.float64).reshape(-1)
    top = int(np.nanargmax(new_y)) if np.isfinite(new_y).any() else 0
    report = ClimbReport(
        start=x_unit[best].copy(),
        end=new_x[top].copy(),
        start_log_likelihood=float(y[best]),
        end_log_likelihood=float(new_y[top]),
        n_evaluations=len(new_y),
        stop_reason="hunt",
    )
    return np.vstack([x_unit, new_x]), np.concatenate([y, new_y]), report
