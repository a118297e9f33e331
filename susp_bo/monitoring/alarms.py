"""Acceptable domains, P(outside) and maintenance alarms over a vehicle's campaigns.

For each campaign and calibrated parameter the posterior draws give the median,
the equal-tailed 95 % interval and ``P(outside) = P(w ∉ [lo, hi] | data)``, the
posterior mass outside the parameter's acceptable domain (Monte Carlo estimate:
the share of draws outside).

Alarm rule, per vehicle and parameter, campaigns in date order:

- a campaign whose calibration is **trusted** (``result.json["reliability"]
  ["verdict"] == "trusted"``) sets the state: alarm when P(outside) exceeds
  the threshold (default 0.9), clear otherwise;
- a campaign whose calibration is **not trusted** (or has no verdict) never
  raises nor clears an alarm: the state carries over and the campaign's row
  says why it was not used.

The maintenance table lists the alarms active after a vehicle's last campaign:
which part, since which campaign (the first trusted campaign of the current
alarm run), with which probability (that of the last trusted campaign).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

ALARM_THRESHOLD = 0.9
BOTH_SIDES_SHARE = 0.25
"""Direction ``both`` when the smaller side holds more than this share of P(outside): the
posterior straddles the acceptable domain and which way the part left it is not known."""
NO_VERDICT = "no reliability verdict: result from an older version"


def p_outside(samples: np.ndarray, acceptable: tuple[float, float]) -> float:
    """Posterior probability of lying outside ``[lo, hi]``: the share of draws outside.

    Args:
        samples: (n,) posterior draws of one parameter (physical unit).
        acceptable: (lo, hi) acceptable domain, same unit.

    Returns:
        P(w < lo or w > hi), in [0, 1].
    """
    draws = np.asarray(samples, dtype=np.float64).reshape(-1)
    if draws.size == 0:
        raise ValueError("samples: no draws")
    bad = int(np.count_nonzero(~np.isfinite(draws)))
    if bad:  # a NaN compares False both ways and would count as inside the domain
        raise ValueError(
            f"samples: {bad} of {draws.size} draws are not finite; expected finite posterior "
            "draws (a non-finite draw is neither inside nor outside the acceptable domain)"
        )
    lo, hi = acceptable
    if not lo < hi:  # also refuses NaN bounds; an infinite bound is a one-sided domain
        raise ValueError(f"acceptable: got ({lo}, {hi}); expected bounds with lower < upper")
    return float(np.mean((draws < lo) | (draws > hi)))


def trust(payload: Mapping[str, Any]) -> tuple[bool, str]:
    """Whether a ``result.json`` payload is trusted, and the sentence that says why (not).

    Contract (shared/DESIGN.md): trusted iff ``reliability.verdict == "trusted"``; a
    payload without the key is not trusted.
    """
    reliability = payload.get("reliability")
    if not isinstance(reliability, Mapping):
        return False, NO_VERDICT
    trusted = reliability.get("verdict") == "trusted"
    sentence = str(reliability.get("sentence") or "")
    if not sentence:
        codes = [str(r.get("code")) for r in reliability.get("reasons", []) or []]
        sentence = "trusted" if trusted else f"not trusted ({', '.join(codes) or 'no reason'})"
    return trusted, sentence


@dataclass(frozen=True)
class ParameterState:
    """One parameter of one campaign.

    Attributes:
        name: parameter name.
        median: posterior median (physical unit).
        interval95: equal-tailed 95 % interval (2.5 %, 97.5 % quantiles).
        p_outside: posterior mass outside the acceptable domain (None: no domain).
        direction: ``below`` / ``above``: the side holding most of that mass; ``both``
            when the smaller side holds more than :data:`BOTH_SIDES_SHARE` of it (a
            posterior wider than the domain: the side cannot be told).
        alarm: the alarm state after this campaign (carried over when not trusted).
        used: whether this campaign could raise or clear the alarm (trusted, with a domain).
        truth: true value (synthetic data), else None.
        truth_outside: whether the truth lies outside the acceptable domain.
    """

    name: str
    median: float
    interval95: tuple[float, float]
    p_outside: float | None
    direction: str | None
    alarm: bool
    used: bool
    truth: float | None = None
    truth_outside: bool | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready."""
        return {
            "median": self.median,
            "interval95": list(self.interval95),
            "p_outside": self.p_outside,
            "direction": self.direction,
            "alarm": self.alarm,
            "used_for_alarm": self.used,
            "truth": self.truth,
            "truth_outside": self.truth_outside,
        }


def summarise_parameter(
    name: str,
    draws: np.ndarray,
    acceptable: tuple[float, float] | None,
) -> tuple[float, tuple[float, float], float | None, str | None]:
    """Median, equal-tailed 95 % interval, P(outside) and its side, from (n,) draws."""
    draws = np.asarray(draws, dtype=np.float64).reshape(-1)
    median = float(np.median(draws))
    lo95, hi95 = (float(v) for v in np.quantile(draws, [0.025, 0.975]))
    if acceptable is None:
        return median, (lo95, hi95), None, None
    below = float(np.mean(draws < acceptable[0]))
    above = float(np.mean(draws > acceptable[1]))
    if below == above == 0.0:
        direction = None
    elif min(below, above) > BOTH_SIDES_SHARE * (below + above):
        direction = "both"  # a posterior wider than the domain: the side cannot be told
    else:
        direction = "below" if below >= above else "above"
    return median, (lo95, hi95), below + above, direction


@dataclass(frozen=True)
class CampaignRecord:
    """What the alarm logic needs of one calibrated campaign.

    Attributes:
        campaign_id: ``vehicle/date``.
        vehicle: vehicle identifier.
        date: ISO date.
        trusted: whether the calibration is trusted.
        why: the reliability sentence (or why no verdict).
        summaries: per parameter name, (median, interval95, p_outside, direction).
        truth: true values of the synthetic data, else None.
    """

    campaign_id: str
    vehicle: str
    date: str
    trusted: bool
    why: str
    summaries: Mapping[str, tuple[float, tuple[float, float], float | None, str | None]]
    truth: Mapping[str, float] | None = None


def apply_alarms(
    records: Sequence[CampaignRecord],
    acceptable: Mapping[str, tuple[float, float] | None],
    threshold: float = ALARM_THRESHOLD,
) -> dict[str, dict[str, ParameterState]]:
    """The alarm state of every parameter after every campaign.

    Args:
        records: campaigns of any vehicles (sorted here by vehicle, then date).
        acceptable: per parameter, its acceptable domain (None: never alarms).
        threshold: alarm when P(outside) > threshold on a trusted calibration.

    Returns:
        ``{campaign_id: {parameter: ParameterState}}``.
    """
    if not 0.0 < threshold < 1.0:
        raise ValueError(f"threshold: got {threshold}; expected a probability in (0, 1)")
    states: dict[str, dict[str, ParameterState]] = {}
    alarm: dict[tuple[str, str], bool] = {}
    for record in sorted(records, key=lambda r: (r.vehicle, r.date)):
        row: dict[str, ParameterState] = {}
        for name, (median, interval, p_out, direction) in record.summaries.items():
            key = (record.vehicle, name)
            used = record.trusted and p_out is not None
            if used:
                alarm[key] = bool(p_out > threshold)
            truth = None if record.truth is None else record.truth.get(name)
            domain = acceptable.get(name)
            truth_outside = (
                None
                if truth is None or domain is None
                else bool(truth < domain[0] or truth > domain[1])
            )
            row[name] = ParameterState(
                name=name,
                median=median,
                interval95=interval,
                p_outside=p_out,
                direction=direction,
                alarm=alarm.get(key, False),
                used=used,
                truth=truth,
                truth_outside=truth_outside,
            )
        states[record.campaign_id] = row
    return states


def histories(records: Sequence[CampaignRecord]) -> dict[str, list[CampaignRecord]]:
    """Each vehicle's campaigns in date order, vehicles sorted."""
    by_vehicle: dict[str, list[CampaignRecord]] = {}
    for record in sorted(records, key=lambda r: (r.vehicle, r.date)):
        by_vehicle.setdefault(record.vehicle, []).append(record)
    return by_vehicle


def maintenance_table(
    records: Sequence[CampaignRecord],
    states: Mapping[str, Mapping[str, ParameterState]],
    descriptions: Mapping[str, str] | None = None,
) -> list[dict[str, Any]]:
    """The alarms active after each vehicle's last campaign.

    Returns:
        One row per (vehicle, parameter) in alarm: ``vehicle``, ``parameter``,
        ``part`` (the parameter's description), ``since_campaign``, ``since_date`` (the
        first of the trusted campaigns in alarm on the same side up to the last one),
        ``probability`` (P(outside) of the last trusted campaign), ``direction``,
        ``last_trusted_campaign``, ``median`` there, and ``untrusted_since``: the
        campaigns after it that could not confirm or clear the alarm.
    """
    descriptions = descriptions or {}
    by_vehicle = histories(records)
    rows: list[dict[str, Any]] = []
    for vehicle, history in by_vehicle.items():
        names = list(states[history[-1].campaign_id])
        for name in names:
            if not states[history[-1].campaign_id][name].alarm:
                continue
            trusted = [r for r in history if states[r.campaign_id][name].used]
            last = trusted[-1]
            state = states[last.campaign_id][name]
            since = last
            for record in reversed(trusted):  # the run of alarms on the same side
                earlier = states[record.campaign_id][name]
                if not earlier.alarm or earlier.direction != state.direction:
                    break
                since = record
            rows.append(
                {
                    "vehicle": vehicle,
                    "parameter": name,
                    "part": descriptions.get(name, name),
                    "since_campaign": since.campaign_id,
                    "since_date": since.date,
                    "probability": state.p_outside,
                    "direction": state.direction,
                    "last_trusted_campaign": last.campaign_id,
                    "median": state.median,
                    "untrusted_since": [
                        r.campaign_id for r in history if r.date > last.date and not r.trusted
                    ],
                }
            )
    return rows


def attention_table(
    records: Sequence[CampaignRecord],
    states: Mapping[str, Mapping[str, ParameterState]],
) -> list[dict[str, Any]]:
    """What the maintenance table cannot say: one row per vehicle whose state is not known.

    A vehicle's last campaign not trusted: its alarms (or their absence) rest on an older
    campaign (``last_campaign``, ``why``, ``last_trusted_campaign`` — None when no campaign
    of the vehicle was trusted). A parameter without an acceptable domain never alarms:
    listed once per vehicle under ``no_domain``.

    Returns:
        Rows ``vehicle``, ``last_campaign``, ``last_trusted``, ``why``,
        ``last_trusted_campaign``, ``no_domain`` (parameter names), only for vehicles
        with something to say.
    """
    by_vehicle = histories(records)
    rows: list[dict[str, Any]] = []
    for vehicle, history in by_vehicle.items():
        last = history[-1]
        trusted = [r for r in history if r.trusted]
        no_domain = [
            name for name, state in states[last.campaign_id].items() if state.p_outside is None
        ]
        if last.trusted and not no_domain:
            continue
        rows.append(
            {
                "vehicle": vehicle,
                "last_campaign": last.campaign_id,
                "last_trusted": last.trusted,
                "why": None if last.trusted else last.why,
                "last_trusted_campaign": trusted[-1].campaign_id if trusted else None,
                "no_domain": no_domain,
            }
        )
    return rows
