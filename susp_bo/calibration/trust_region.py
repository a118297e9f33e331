"""Search box (trust region) of the calibration loop: zoom onto a sharp posterior.

Why. With paired data (each measured run on its own measured track) the posterior of
the demo's seven parameters is 5e-5 to 3e-3 of each admissible width wide, while log L
falls by 10³–10⁴ nats across C_w. One stationary GP over the whole of C_w cannot model
both scales: its lengthscales follow the far field, the refinement never resolves the
peak and the search stops tens of nats below the true maximum (benchmarks/coverage.py,
issue 10). The loop therefore works in a *search box* B ⊂ C_w that follows the
posterior:

- the surrogate is fitted in B's own unit cube, on the evaluations inside B widened by
  ``margin`` box widths on each side (at least ``min_points`` of them: the nearest in
  box-scaled Chebyshev distance); its lengthscale priors, the acquisition, the
  refinement candidates, the held-out check and the final MCMC all live in B;
- :func:`next_box` *shrinks* a coordinate of B to the surrogate posterior's median ±
  ``half_width_sd`` posterior sd (never excluding the best evaluated point — with the
  opt-in trust region, nor any evaluation within :func:`posterior_reach` of the best,
  :func:`held_points`, to which the loop also widens B) when that is at most
  ``max_ratio`` of B's current width, and *grows* B (one box width outwards, within C_w)
  on any side where posterior draws press against an inner face of B — so a box that
  missed the mass moves to it instead of truncating it;
- :func:`box_edge` turns a posterior that still presses against an inner face at the
  end, or an evaluation within reach of the best outside the final box, into the
  reliability reason ``search_box_edge`` (the box cut the posterior: the result is not
  trusted).

The prior is uniform on C_w; restricted to B it is uniform on B, so the posterior in
B is the posterior on C_w whenever B holds its mass — which :func:`box_edge` checks.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy import stats

from susp_bo.calibration.design import from_unit, to_unit

Reason = dict

TAIL_RATIO = 5e-4
"""Density at an inner box face over the density at the median (:func:`tail_at_faces`)
above which the box cut heavy tails (outside probe, session 25: a Cauchy of scale 1e-3
with ``trust_region=True``, its box at ±16–24 scales, `trusted` with 95 % intervals half
the exact width; a Gaussian reaches this ratio only 3.9 sd from its mode, half way to the
box's 8 sd)."""
OUTSIDE_SHARE = 0.02
"""Posterior mass outside the final box (:func:`.box_mass.share_outside_box`) from which
the box counts as having cut the posterior."""
TAIL_DRAWS = 2
"""Draws in a face's 5 % strip from which :func:`next_box` counts the refinement's (few)
draws' density there as a tail the box cut (one stray draw of an early surrogate is not)."""
REACH_LEVEL = 0.999
"""A point whose log L is within ½ χ²_q(REACH_LEVEL) of the best holds posterior mass."""


def posterior_reach(q: int) -> float:
    """½ χ²_q(:data:`REACH_LEVEL`) in nats: how far below the best log L mass still counts."""
    return 0.5 * float(stats.chi2.ppf(REACH_LEVEL, q))


def points_within_reach(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The evaluations whose log L is within :func:`posterior_reach` of the best.

    Args:
        x: (n x q) evaluated parameters (any unit).
        y: (n,) log L (nats); NaN for a failed run.

    Returns:
        (k x q) those rows of ``x`` (k >= 1 when any run succeeded, else 0).
    """
    y = np.asarray(y, dtype=np.float64)
    finite = np.isfinite(y)
    if not finite.any():
        return np.asarray(x)[:0]
    near = finite & (np.where(finite, y, -np.inf) >= y[finite].max() - posterior_reach(x.shape[1]))
    return np.asarray(x)[near]


def training_mask(
    x: np.ndarray, box: np.ndarray, margin: float = 0.5, min_points: int = 10
) -> np.ndarray:
    """Which evaluations the surrogate of box ``box`` is fitted on.

    Args:
        x: (n x q) evaluated parameters, physical units.
        box: (2 x q) search box, physical units.
        margin: points up to ``margin`` box widths outside the box on every side are kept.
        min_points: at least this many points are kept (the nearest to the box centre in
            box-scaled Chebyshev distance), or all of them when n is smaller.

    Returns:
        (n,) boolean mask.
    """
    u = to_unit(np.asarray(x, dtype=np.float64), box)
    distance = np.max(np.abs(u - 0.5), axis=1)  # 0.5 on the box faces
    keep = distance <= 0.5 + margin
    if keep.sum() < min(min_points, len(x)):
        nearest = np.argsort(distance, kind="stable")[: min(min_points, len(x))]
        keep[nearest] = True
    return keep


def _inner_faces(box: np.ndarray, bounds: np.ndarray) -> np.ndarray:
    """(2 x q) True where a face of ``box`` lies strictly inside C_w."""
    width = bounds[1] - bounds[0]
    return np.stack([box[0] > bounds[0] + 1e-12 * width, box[1] < bounds[1] - 1e-12 * width])


def face_pressure(draws_local: np.ndarray, strip: float = 0.05) -> np.ndarray:
    """(2 x q) share of the draws within ``strip`` box widths of each face (lower, upper).

    Args:
        draws_local: (n x q) posterior draws in the box's unit cube.
        strip: strip width as a fraction of the box width.
    """
    u = np.asarray(draws_local, dtype=np.float64)
    return _strip_counts(u, strip) / u.shape[0]


def _strip_counts(u: np.ndarray, strip: float) -> np.ndarray:
    """(2 x q) the draws ``u`` (n x q, box unit cube) within ``strip`` of each face."""
    return np.stack([np.sum(u < strip, axis=0), np.sum(u > 1.0 - strip, axis=0)])


def _peak_count(u: np.ndarray, strip: float) -> np.ndarray:
    """(q,) the draws within a ``strip``-wide band around the median (at least 1)."""
    centre = np.median(u, axis=0)
    return np.maximum(np.sum(np.abs(u - centre) < strip / 2, axis=0), 1)


def held_points(x: np.ndarray, y: np.ndarray, within_reach: bool) -> np.ndarray:
    """(k x q) the evaluations a search box must hold (physical units).

    With ``within_reach`` (the opt-in trust region, ``CalibrationSettings.trust_region``)
    every evaluation within :func:`posterior_reach` of the best log L — a second mode the
    surrogate's draws may not show; without it (the box of the local phase, which follows
    its Laplace approximation) the best evaluation alone, as the README demo's reference
    results were made (an evaluation within reach that such a box leaves out makes the
    verdict ``search_box_edge``: :func:`box_edge`). (0 x q) when no run succeeded.
    """
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    if within_reach:
        return points_within_reach(x, y)
    if not np.isfinite(y).any():
        return x[:0]
    return best_point(x, y)[None, :]


def best_point(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """(q,) the successful evaluation with the highest log L (``y`` needs a finite value)."""
    finite = np.isfinite(y)
    return x[finite][int(np.argmax(y[finite]))]


def hold_points(box: np.ndarray, held: np.ndarray) -> np.ndarray:
    """``box`` (2 x q) widened, where needed, to hold every row of ``held`` (k x q; physical
    units); unchanged when ``held`` is empty."""
    box = np.asarray(box, dtype=np.float64)
    held = np.asarray(held, dtype=np.float64)
    if held.size == 0:
        return box
    return np.stack([np.minimum(box[0], held.min(axis=0)), np.maximum(box[1], held.max(axis=0))])


def next_box(
    draws_local: np.ndarray,
    box: np.ndarray,
    bounds: np.ndarray,
    keep: np.ndarray,
    half_width_sd: float = 8.0,
    max_ratio: float = 0.5,
    pressure: float = 0.01,
) -> np.ndarray | None:
    """The next search box, or None when it stays as it is.

    Args:
        draws_local: (n x q) surrogate posterior draws in ``box``'s unit cube.
        box: (2 x q) current search box, physical units.
        bounds: (2 x q) admissible bounds C_w.
        keep: (q,) or (k x q) evaluated points, physical units (:func:`held_points`), that
            a *shrunk* coordinate keeps inside (a coordinate that does not shrink keeps its
            extent; the loop widens the opt-in trust region to them with
            :func:`hold_points`). Empty: the posterior's extent alone.
        half_width_sd: half-width of a shrunk coordinate in posterior sd.
        max_ratio: a coordinate shrinks only to at most this fraction of its width.
        pressure: share of the draws in the 5 % strip at an inner face above which the box
            grows on that side (a flat posterior puts 0.05 there). It also grows where the
            draws' density at an inner face exceeds :data:`TAIL_RATIO` of their peak's (from
            :data:`TAIL_DRAWS` draws in the strip): the tails that :func:`box_edge` would
            find the final box cut (outside probe, session 30: a weakly identified
            parameter's posterior, 3.7× wider than the local phase's Laplace sd, at 3.9e-2
            of its peak at a face the refinement never moved).

    Returns:
        (2 x q) new box inside C_w, or None.
    """
    box = np.asarray(box, dtype=np.float64)
    bounds = np.asarray(bounds, dtype=np.float64)
    d = from_unit(np.asarray(draws_local, dtype=np.float64), box)
    centre = np.median(d, axis=0)
    sd = d.std(axis=0)
    held = np.atleast_2d(np.asarray(keep, dtype=np.float64))
    lo, hi = centre - half_width_sd * sd, centre + half_width_sd * sd
    if held.size:
        lo, hi = np.minimum(lo, held.min(axis=0)), np.maximum(hi, held.max(axis=0))
    pad = 0.05 * (hi - lo)
    lo, hi = lo - pad, hi + pad
    width = box[1] - box[0]
    new = box.copy()
    shrink = (hi - lo) <= max_ratio * width
    new[0, shrink] = lo[shrink]
    new[1, shrink] = hi[shrink]
    grow = ((face_pressure(draws_local) > pressure) | _tails_cut(draws_local)) & _inner_faces(
        box, bounds
    )
    new[0] = np.where(grow[0], box[0] - width, new[0])
    new[1] = np.where(grow[1], box[1] + width, new[1])
    new = np.stack([np.maximum(new[0], bounds[0]), np.minimum(new[1], bounds[1])])
    tiny = (new[1] - new[0]) <= 1e-9 * (bounds[1] - bounds[0])
    new[:, tiny] = box[:, tiny]  # a degenerate coordinate keeps its old extent
    if np.array_equal(new, box):
        return None
    return new


def tail_at_faces(draws_local: np.ndarray, strip: float = 0.05) -> np.ndarray:
    """(2 x q) the posterior's density at each face against its peak, per coordinate: the
    draws within ``strip`` box widths of a face over those within the same width around the
    median (a Gaussian cut at 8 sd: ~1e-14, no draw there; a Cauchy cut at 20 scales: ~3e-3).

    Args:
        draws_local: (n x q) posterior draws in the box's unit cube.
        strip: strip width as a fraction of the box width.
    """
    u = np.asarray(draws_local, dtype=np.float64)
    return _strip_counts(u, strip) / _peak_count(u, strip)


def _tails_cut(draws_local: np.ndarray, strip: float = 0.05) -> np.ndarray:
    """(2 x q) True where the draws' density at a face exceeds :data:`TAIL_RATIO` of their
    peak's, counted from at least :data:`TAIL_DRAWS` draws in the face's strip."""
    u = np.asarray(draws_local, dtype=np.float64)
    count = _strip_counts(u, strip)
    return (count / _peak_count(u, strip) > TAIL_RATIO) & (count >= TAIL_DRAWS)


def _faces(
    mask: np.ndarray, box: np.ndarray, names: Sequence[str], ratio: np.ndarray | None = None
) -> str:
    """ "name (side face value[: ratio of the peak])", for each (2 x q) ``mask`` entry."""
    return ", ".join(
        f"{names[k]} ({side} face {box[s, k]:.4g}"
        + ("" if ratio is None else f": {ratio[s, k]:.1e} of the peak")
        + ")"
        for s, side in enumerate(("lower", "upper"))
        for k in range(len(names))
        if mask[s, k]
    )


def box_edge(
    draws_local: np.ndarray,
    box: np.ndarray,
    bounds: np.ndarray,
    names: Sequence[str],
    pressure: float = 0.01,
    x: np.ndarray | None = None,
    y: np.ndarray | None = None,
    outside_share: float | None = 0.0,
) -> Reason | None:
    """``search_box_edge`` when the final box cut the posterior.

    Evidence: the final posterior presses against an inner box face; its density at an
    inner face is not negligible against its peak (:data:`TAIL_RATIO`: heavy tails); an
    evaluation *outside* the box has a log L within :func:`posterior_reach` of the best
    (posterior mass the box left out, e.g. a second mode: no draw can press against a
    face when the mass lies beyond it); or a surrogate of all of C_w is sure of mass
    outside (``outside_share``). Outside probe, session 25.

    Args:
        draws_local: (n x q) final posterior draws in the box's unit cube.
        box: (2 x q) final search box, physical units.
        bounds: (2 x q) admissible bounds C_w.
        names: (q,) parameter names.
        pressure: as in :func:`next_box`.
        x: (m x q) evaluated parameters, physical units (None: not looked at).
        y: (m,) their log L (nats), NaN for a failed run.
        outside_share: the posterior mass outside the box that a surrogate of all of C_w
            is sure of (:func:`.box_mass.share_outside_box`); at least
            :data:`OUTSIDE_SHARE` of it is a third kind of evidence (a broad, low mode);
            None: not estimated (no evidence either way).
    """
    hit = (face_pressure(draws_local) > pressure) & _inner_faces(box, bounds)
    findings: list[str] = []
    reason: Reason = {"code": "search_box_edge"}
    touched: set[str] = {names[k] for k in np.nonzero(hit.any(axis=0))[0]}
    if hit.any():
        findings.append(
            "the posterior presses against the search box, which cut it: " + _faces(hit, box, names)
        )
    if x is not None and y is not None and len(y):
        held = points_within_reach(np.asarray(x, dtype=np.float64), y)
        tol = 1e-9 * (bounds[1] - bounds[0])
        past = (held < box[0] - tol) | (held > box[1] + tol)  # (k x q)
        outside = past.any(axis=1)
        if outside.any():
            beyond = past[outside].any(axis=0)
            touched |= {names[k] for k in np.nonzero(beyond)[0]}
            findings.append(
                f"{int(outside.sum())} evaluation(s) outside the search box have log L within "
                f"{posterior_reach(len(names)):.3g} nats of the best (beyond the box in "
                + ", ".join(names[k] for k in np.nonzero(beyond)[0])
                + "): the box left out posterior mass"
            )
            reason["evaluations_outside_box"] = int(outside.sum())
    tails = tail_at_faces(draws_local) * _inner_faces(box, bounds)
    tails[hit] = 0.0  # already said: pressed against that face
    if (tails > TAIL_RATIO).any():
        findings.append(
            "the posterior's density at the search box's faces is not negligible against its "
            "peak — heavy tails the box cut off: "
            + _faces(tails > TAIL_RATIO, box, names, ratio=tails)
        )
        touched |= {names[k] for k in np.nonzero((tails > TAIL_RATIO).any(axis=0))[0]}
        reason["tail_at_face"] = float(tails.max())
    if outside_share is not None and outside_share >= OUTSIDE_SHARE:
        findings.append(  # a lower estimate: rounded down, never "at least 100 %"
            f"a surrogate of all of C_w puts at least {min(99, math.floor(100 * outside_share))}"
            " % of the "
            "posterior mass outside the search box (a broad mode whose peak lies below the "
            "best log L)"
        )
        reason["mass_outside_box"] = float(outside_share)
    if not findings:
        return None
    reason["message"] = "; ".join(findings)
    reason["parameters"] = sorted(touched)
    return reason


def to_global_unit(draws_local: np.ndarray, box: np.ndarray, bounds: np.ndarray) -> np.ndarray:
    """Draws in the box's unit cube → the unit cube of C_w (same shape)."""
    d = np.asarray(draws_local, dtype=np.float64)
    q = d.shape[-1]
    flat = to_unit(from_unit(d.reshape(-1, q), box), bounds)
    return flat.reshape(d.shape)
