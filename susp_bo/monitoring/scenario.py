"""A known-answer degradation scenario: a monitoring folder of synthetic campaigns.

Two vehicles are measured on the same series of dates: on the *degrading*
vehicle one parameter (by default the secondary vertical damper) loses its value
linearly from the nominal to ``final`` over the campaigns; the *healthy* vehicle
keeps every parameter at its nominal. Each campaign is ``nu`` synthetic runs on
fresh track realizations (seeds differ per vehicle and campaign), written as
``FOLDER/<vehicle>/<date>/run_*.h5`` with vehicle, date and line in the run
metadata and a ``campaign.toml`` manifest, exactly as real campaigns would be.

The answer is known, so a monitoring run on the folder can be scored: the
campaign at which the alarm rises (P(outside) > 0.9) against the campaign at
which the truth left the acceptable domain, and false alarms on the healthy
vehicle (:func:`score_scenario`).
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import itertools
import json
import tomllib
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import tomli_w

from susp_bo.calibration.budget import budget_requirement
from susp_bo.data.run_files import save_run
from susp_bo.data.synthetic import check_synthesis, synthesize_runs
from susp_bo.monitoring.alarms import CampaignRecord, apply_alarms
from susp_bo.monitoring.campaigns import MANIFEST_NAME, safe_name
from susp_bo.rig.catalog import rig_path
from susp_bo.rig.spec import RigSpec, load_rig_spec

DEGRADING = "TRAIN-A"
HEALTHY = "TRAIN-B"
PARAMETER = "secondary_vertical_damping"
CALIBRATED = ("secondary_vertical_damping", "yaw_damper_damping")


def campaign_dates(
    n: int, start: dt.date = dt.date(2026, 1, 15), every_days: int = 30
) -> list[dt.date]:
    """``n`` campaign dates, ``every_days`` apart from ``start``."""
    return [start + dt.timedelta(days=every_days * k) for k in range(n)]


def linear_degradation(nominal: float, final: float, n: int) -> np.ndarray:
    """(n,) values from ``nominal`` (first campaign) to ``final`` (last), linearly."""
    return np.linspace(nominal, final, n)


def write_campaign(
    spec: RigSpec,
    folder: Path,
    *,
    vehicle: str,
    date: dt.date,
    truth: Mapping[str, float],
    nu: int,
    seed: int,
    noise_m_s2: float,
    line: str = "synthetic test line",
) -> Path:
    """``nu`` synthetic runs of one campaign, with its metadata and manifest, in ``folder``.

    The values are written as given (a vehicle that discovery refuses can be written, to
    test the refusal); the manifest is written last, so its presence marks a finished
    campaign.
    """
    runs = synthesize_runs(spec, truth, nu=nu, seed=seed, noise_m_s2=noise_m_s2)
    folder.mkdir(parents=True, exist_ok=True)
    for index, run in enumerate(runs):
        metadata = {**run.metadata, "vehicle": vehicle, "date": date.isoformat(), "line": line}
        save_run(dataclasses.replace(run, metadata=metadata), folder / f"run_{index:03d}.h5")
    write_manifest(folder, vehicle=vehicle, date=date, line=line)
    return folder


def write_manifest(folder: Path, *, vehicle: str, date: dt.date, line: str = "") -> Path:
    """``folder/campaign.toml`` with ``vehicle``, ``date`` (a TOML date) and ``line``.

    Written by a TOML writer, so any string (quotes, backslashes, new lines) reads back as
    given.
    """
    path = folder / MANIFEST_NAME
    path.write_text(
        tomli_w.dumps({"vehicle": vehicle, "date": date, "line": line}), encoding="utf-8"
    )
    return path


def _check_scenario_arguments(
    n_campaigns: object, vehicles: object, dates: object
) -> tuple[list[str], list[dt.date]]:
    """The vehicle ids and dates of :func:`write_scenario`, checked.

    ``dates`` None gives :func:`campaign_dates` (``n_campaigns`` of them).

    Raises:
        ValueError: naming the argument, the value and what is allowed.
    """
    if isinstance(n_campaigns, bool) or not isinstance(n_campaigns, int) or n_campaigns < 2:
        raise ValueError(
            f"n_campaigns: got {n_campaigns!r}; expected an integer >= 2 (the degradation runs "
            "from the nominal at the first campaign to final at the last)"
        )
    if isinstance(vehicles, (str, bytes)) or not isinstance(vehicles, Sequence):
        raise ValueError(
            f"vehicles: got {vehicles!r}; expected a sequence of vehicle ids, e.g. "
            f"({DEGRADING!r}, {HEALTHY!r}) or ({DEGRADING!r},) (a string is not a sequence of ids)"
        )
    names = list(vehicles)
    if not names:
        raise ValueError(
            "vehicles: got an empty sequence; expected 1 or more vehicle ids (the first "
            "degrades, the others stay healthy)"
        )
    for name in names:
        if not isinstance(name, str) or not name or safe_name(name) != name:
            raise ValueError(
                f"vehicles: {name!r} is not allowed; expected a non-empty string of letters, "
                "digits, '-', '_' and '.' that does not start or end with '.' or '_' (it is "
                "the vehicle's folder name, as given)"
            )
    folded = [name.casefold() for name in names]
    repeated = sorted({n for n, f in zip(names, folded) if folded.count(f) > 1})
    if repeated:
        raise ValueError(
            f"vehicles: {repeated} given more than once (letter case ignored) in {names}; "
            "expected distinct vehicle ids"
        )
    if dates is None:
        return names, campaign_dates(n_campaigns)
    if isinstance(dates, (str, bytes)) or not isinstance(dates, Sequence):
        raise ValueError(
            f"dates: got {dates!r}; expected a sequence of datetime.date values, one per campaign"
        )
    checked: list[dt.date] = []
    for date in dates:
        if not isinstance(date, dt.date) or isinstance(date, dt.datetime):
            raise ValueError(
                f"dates: {date!r} is not allowed; expected datetime.date values (no time)"
            )
        checked.append(date)
    if len(checked) != n_campaigns:
        raise ValueError(
            f"dates: {len(checked)} given for n_campaigns = {n_campaigns}; expected one date "
            "per campaign"
        )
    for earlier, later in itertools.pairwise(checked):
        if not earlier < later:
            raise ValueError(
                f"dates: {[d.isoformat() for d in checked]} are not strictly increasing "
                f"({earlier.isoformat()} then {later.isoformat()}); expected distinct dates in "
                "increasing order (the degradation follows them)"
            )
    return names, checked


def write_scenario(
    spec: RigSpec,
    folder: str | Path,
    *,
    parameter: str = "secondary_vertical_damping",
    final: float = 21.0e3,
    n_campaigns: int = 10,
    nu: int = 2,
    seed: int = 0,
    noise_m_s2: float = 0.005,
    vehicles: Sequence[str] = (DEGRADING, HEALTHY),
    dates: Sequence[dt.date] | None = None,
) -> dict[str, Any]:
    """Write the scenario's campaigns (skipping those already written) and return its truth.

    Args:
        spec: the rig the synthetic runs come from.
        folder: monitoring folder to fill.
        parameter: the degrading parameter (a calibration parameter of ``spec``).
        final: its value at the last campaign (physical unit).
        n_campaigns: campaigns per vehicle.
        nu: measured runs per campaign.
        seed: master seed.
        noise_m_s2: sensor noise (m/s² rms).
        vehicles: (degrading, healthy) vehicle ids; a single id = degrading only.
        dates: campaign dates (default monthly from 2026-01-15).

    Returns:
        ``{"parameter", "dates", "truth": {vehicle: [value per campaign]}}``.

    Raises:
        ValueError: before anything is written, naming the argument, the value and what is
            allowed: a parameter outside the calibration set, a ``final`` the rig refuses,
            ``n_campaigns`` below 2, ``vehicles`` a string, empty, with an id that is not a
            plain folder name or repeated (letter case ignored), ``dates`` not one
            ``datetime.date`` per campaign in strictly increasing order, or a bad ``nu``,
            ``seed`` or ``noise_m_s2``.
    """
    root = Path(folder)
    names = spec.calibration_names
    if parameter not in names:
        raise ValueError(f"parameter: {parameter!r} is not in the calibration set {list(names)}")
    nominal = float(spec.parameters[parameter])
    vehicles, dates = _check_scenario_arguments(n_campaigns, vehicles, dates)
    try:
        spec.with_parameters({parameter: final})
    except ValueError as error:
        raise ValueError(f"final: {error}") from None
    check_synthesis(nu, seed, noise_m_s2)  # before the first campaign is written
    values = {
        vehicles[0]: linear_degradation(nominal, final, n_campaigns),
        **{v: np.full(n_campaigns, nominal) for v in vehicles[1:]},
    }
    for v, vehicle in enumerate(vehicles):
        for k, date in enumerate(dates):
            target = root / vehicle / date.isoformat()
            if (target / MANIFEST_NAME).is_file():
                continue
            write_campaign(
                spec,
                target,
                vehicle=vehicle,
                date=date,
                truth={parameter: float(values[vehicle][k])},
                nu=nu,
                seed=int(np.random.SeedSequence([seed, v, k]).generate_state(1)[0]),
                noise_m_s2=noise_m_s2,
            )
    return {
        "parameter": parameter,
        "dates": [d.isoformat() for d in dates],
        "truth": {vehicle: values[vehicle].tolist() for vehicle in vehicles},
    }


def score_scenario(payload: Mapping[str, Any], parameter: str) -> dict[str, Any]:
    """Detection delay and false alarms of a ``monitor.json`` payload on synthetic campaigns.

    For every vehicle: the first campaign whose truth lies outside the acceptable
    domain, the first campaign in alarm, the delay between them (in campaigns;
    negative = an alarm before the truth left the band), and the campaigns in
    alarm while the truth was inside (false alarms), for ``parameter`` and for
    every other calibrated parameter.
    """
    result: dict[str, Any] = {}
    for vehicle in payload["vehicles"]:
        rows = [r for r in payload["campaigns"] if r["vehicle"] == vehicle]
        per_parameter = {}
        for name in payload["parameters"]:
            states = [r["parameters"][name] for r in rows]
            left = next((k for k, s in enumerate(states) if s["truth_outside"]), None)
            raised = next((k for k, s in enumerate(states) if s["alarm"]), None)
            false = [
                rows[k]["id"] for k, s in enumerate(states) if s["alarm"] and not s["truth_outside"]
            ]
            per_parameter[name] = {
                "truth_left_band_at": left,
                "alarm_raised_at": raised,
                "delay_campaigns": None if left is None or raised is None else raised - left,
                "false_alarms": false,
                "p_outside": [s["p_outside"] for s in states],
                "truth": [s["truth"] for s in states],
                "trusted": [r["trusted"] for r in rows],
            }
        result[vehicle] = per_parameter
    return result


def as_if_trusted(payload: Mapping[str, Any]) -> dict[str, Any]:
    """A copy of a ``monitor.json`` payload with every calibration taken as trusted.

    For scoring the calibrations alone where no reliability verdict exists (a
    result of a version without verdicts counts as not trusted, so it raises no alarm).
    """
    copy = json.loads(json.dumps(payload))
    records = [
        CampaignRecord(
            row["id"],
            row["vehicle"],
            row["date"],
            True,
            "taken as trusted",
            {
                name: (s["median"], tuple(s["interval95"]), s["p_outside"], s["direction"])
                for name, s in row["parameters"].items()
            },
            row["truth"],
        )
        for row in copy["campaigns"]
    ]
    acceptable = {
        name: None if a is None else tuple(a)
        for name, a in zip(copy["parameters"], copy["acceptable"])
    }
    states = apply_alarms(records, acceptable, copy["alarm_threshold"])
    for row in copy["campaigns"]:
        row["trusted"] = True
        row["parameters"] = {n: s.to_dict() for n, s in states[row["id"]].items()}
    return copy


def short_rig(path: Path, duration_s: float, warm_up_s: float = 2.0) -> Path:
    """The reference rig with ``duration_s`` records, 4 s Welch segments, 0.5–20 Hz, at ``path``."""
    document = tomllib.loads(rig_path("hst_trailer").read_text())
    document["rig"]["name"] = "hst_trailer_monitoring"
    document["simulation"].update(duration_s=duration_s, warm_up_s=warm_up_s)
    document["spectrum"].update(segment_s=4.0, f_min_hz=0.5, n_frequencies=32)
    path.write_text(tomli_w.dumps(document))
    return path


def run_scenario(
    out: str | Path,
    *,
    n_campaigns: int = 10,
    final: float = 21.0e3,
    nu: int = 2,
    duration_s: float = 10.0,
    budget: int = 20,
    workers: int | None = 1,
    mcmc: Mapping[str, int] | None = None,
    vehicles: Sequence[str] = (DEGRADING, HEALTHY),
    progress: bool = True,
    error_model: str = "unpaired",
    local_search: bool = False,
    warm_start: bool = True,
    warm_budget: int | None = None,
) -> dict[str, Any]:
    """Write the scenario under ``out/campaigns``, monitor it into ``out/monitor``, score it.

    q = 2 (:data:`CALIBRATED`: the degrading damper and the yaw damper), on
    :func:`short_rig`; ``budget`` evaluations per campaign (a third of them the
    design, batches of 4, 4 check points). Resumable: finished campaigns are read back.
    ``error_model`` (``unpaired`` or ``paired``) and ``local_search`` go to the
    campaigns' ``[output_error] model`` and ``[search] local``; ``warm_start`` and
    ``warm_budget`` to :func:`~susp_bo.monitoring.runner.monitor`.

    Returns:
        ``{"truth", "monitor" (the monitor.json payload), "with_reliability_contract",
        "every_calibration_taken_as_trusted"}`` (the last two from :func:`score_scenario`).
    """
    from susp_bo.monitoring.runner import monitor

    root = Path(out).resolve()
    data = root / "campaigns"
    data.mkdir(parents=True, exist_ok=True)
    rig = short_rig(root / "hst_trailer_monitoring.toml", duration_s)
    truth = write_scenario(
        load_rig_spec(rig),
        data,
        parameter=PARAMETER,
        final=final,
        n_campaigns=n_campaigns,
        nu=nu,
        seed=2026,
        vehicles=vehicles,
    )
    design = max(8, budget // 3) if budget >= 8 else budget
    check = 4 if budget >= 12 else 0
    minimum = budget_requirement(len(CALIBRATED), design, 4, check).minimum
    (data / "monitor.toml").write_text(
        tomli_w.dumps(
            {
                "rig": str(rig),
                "parameters": list(CALIBRATED),
                "budget": {
                    "max_evaluations": budget,
                    "initial_design": design,
                    "batch_size": 4,
                    "check_points": check,
                    # a smoke-sized budget runs, and its calibrations say they are not trusted
                    "allow_small": budget < minimum,
                },
                "seeds": {"calibration": 0, "mcmc": 1},
                "mcmc": dict(mcmc or {"chains": 128, "draws": 1000, "warmup": 300}),
                "output_error": {"model": error_model},
                "search": {"local": bool(local_search)},
            }
        )
    )
    payload = monitor(
        data,
        root / "monitor",
        workers=workers,
        progress=progress,
        warm_start=warm_start,
        warm_budget=warm_budget,
    )
    return {
        "truth": truth,
        "monitor": payload,
        "with_reliability_contract": score_scenario(payload, PARAMETER),
        "every_calibration_taken_as_trusted": score_scenario(as_if_trusted(payload), PARAMETER),
    }
