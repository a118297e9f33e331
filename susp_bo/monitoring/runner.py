"""``susp-bo monitor``: calibrate every campaign of a monitoring folder, then trends and alarms.

Each campaign is one calibration study (:func:`susp_bo.calibration.study.run_study`)
with its own results folder ``OUT/<vehicle>/<date>/`` (store, ``result.json``,
``posterior_samples.npy``, figures, log). The run is resumable at the campaign
level and inside a campaign:

- a campaign whose folder holds ``result.json`` and ``posterior_samples.npy`` is
  finished and never recomputed (its result is read back);
- a campaign whose folder holds only an evaluation store was killed: it is
  resumed from the store (``resume=True``: finished simulations are read back
  bit for bit, the result equals that of an uninterrupted run);
- a campaign added to the monitoring folder later is simply new work.

Before any simulation the budget and every campaign are checked
(:mod:`~susp_bo.monitoring.campaign_checks`): a finished or
interrupted campaign is reused only if its evaluation store's fingerprint matches the
runs now in its folder, the rig and the output error
(:mod:`~susp_bo.monitoring.campaign_results`), and a finished one only if its result and
draws are readable; otherwise the run stops naming the results folder and what to do,
and nothing is written.

Execution: campaigns run **in sequence**, each study's simulator runs in
parallel on the process pool (``workers``) or the Dask cluster (``scheduler``).
An EGO batch (``batch_size`` points × ν track stretches) already fills the
workers, and the surrogate fit and the MCMC of a campaign are serial in the
driver, so running campaigns side by side would only pay off with more
workers than a batch needs; in sequence the result of each campaign is also
final (and resumable) before the next starts.

Settings common to every campaign come from an optional ``monitor.toml`` in
the monitoring folder — the keys of a study config (``rig``, ``parameters``,
``[budget]``, ``[seeds]``, ``[executor]``, ``[mcmc]``, ``[output_error]``, ``[search]``)
except ``data`` and ``out`` — overridden by the arguments.
"""

from __future__ import annotations

import dataclasses
import numbers
import sys
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from susp_bo import __version__
from susp_bo.calibration.study import RESULT_NAME, SAMPLES_NAME, run_study
from susp_bo.calibration.study_inputs import StudyError
from susp_bo.calibration.study_preparation import STORE_NAME
from susp_bo.json_files import json_ready, write_json
from susp_bo.monitoring.alarms import (
    ALARM_THRESHOLD,
    CampaignRecord,
    apply_alarms,
    attention_table,
    maintenance_table,
    summarise_parameter,
    trust,
)
from susp_bo.monitoring.campaign_checks import check_campaign, small_budget_problem, with_budget
from susp_bo.monitoring.campaign_results import CampaignResultError, read_finished
from susp_bo.monitoring.campaigns import Campaign, CampaignError, discover_campaigns
from susp_bo.monitoring.warm_start import plan_warm_start
from susp_bo.output_folder import check_output_files
from susp_bo.output_lock import OutputFolderBusy, refuse_if_busy
from susp_bo.rig.schema import did_you_mean
from susp_bo.rig.spec import load_rig_spec
from susp_bo.rig.toml_files import TomlFileError, read_toml
from susp_bo.study_config import ExecutorConfig, StudyConfig, parse_study_config
from susp_bo.study_sections import SECTIONS

MONITOR_CONFIG_NAME = "monitor.toml"
MONITOR_NAME = "monitor.json"


class MonitorError(ValueError):
    """A monitoring run that cannot start: bad folder, settings or campaign."""


ARGUMENTS = ("rig", "parameters", "budget", "warm_budget", "workers", "scheduler", "out")
API_NAMES = {name: name for name in ARGUMENTS}
"""How errors name the arguments of :func:`monitor` called from Python (its keywords)."""
CLI_NAMES = {name: "--" + name.replace("_", "-") for name in ARGUMENTS}
"""How errors name them for ``susp-bo monitor`` (its flags)."""


def _flag_error(flag: str, key: str, error: Exception) -> MonitorError:
    """``error`` (a message ``"<key>: …"`` of the study config) blamed on ``flag``."""
    text = str(error)
    return MonitorError(f"{flag}: {text.removeprefix(f'{key}: ')}")


def base_config(
    folder: Path,
    out: Path,
    *,
    rig: str | None = None,
    parameters: Sequence[str] | None = None,
    budget: int | None = None,
    workers: int | None = None,
    scheduler: str | None = None,
    allow_small_budget: bool = False,
    arguments: Mapping[str, str] = CLI_NAMES,
) -> StudyConfig:
    """The study config every campaign shares (``data``/``out`` set per campaign).

    The arguments override ``monitor.toml``; a bad argument is refused naming it as
    ``arguments`` does (:data:`CLI_NAMES`: ``--rig``, ``--parameters``, …;
    :data:`API_NAMES`: the keywords), a bad value of the file naming the file. A rig path
    given as an argument is relative to the current folder, one in ``monitor.toml`` to the
    monitoring folder.

    Raises:
        MonitorError: a bad ``monitor.toml`` or argument.
    """
    path = folder / MONITOR_CONFIG_NAME
    mapping: dict[str, Any] = {}
    if path.exists() and not path.is_file():  # a folder was ignored (outside probe, s. 29)
        raise MonitorError(f"{path}: not a file; expected the monitoring settings (TOML)")
    if path.is_file():
        try:
            mapping = read_toml(path)
        except TomlFileError as error:  # not UTF-8 text, or not valid TOML: names the file
            raise MonitorError(str(error)) from None
        for key in ("data", "out"):
            if key in mapping:
                raise MonitorError(
                    f"{path}: {key}: not allowed here; campaigns are discovered in the "
                    "monitoring folder and results go to --out"
                )
        allowed = ("rig", "parameters", *SECTIONS)  # a study file's keys but data and out
        for key in mapping:
            if key not in allowed:
                raise MonitorError(
                    f"{path}: {key}: unknown key{did_you_mean(key, allowed)}; allowed keys: "
                    f"{', '.join(allowed)}"
                )
    mapping.setdefault("rig", "hst_trailer")
    paths = {"data": ".", "out": str(out)}
    if rig is not None:  # checked alone (relative to the current folder), then used as is
        try:
            mapping["rig"] = parse_study_config({"rig": str(rig), **paths}, Path.cwd()).rig
        except (ValueError, TypeError) as error:
            raise _flag_error(arguments["rig"], "rig", error) from None
    if parameters is not None:
        if isinstance(parameters, str) or not isinstance(parameters, Iterable):
            example = [parameters] if isinstance(parameters, str) else ["yaw_damper_damping"]
            raise MonitorError(
                f"{arguments['parameters']}: {parameters!r} is not allowed; expected a "
                f"non-empty list of distinct calibration parameter names, e.g. {example!r}"
            )
        try:  # the list alone (distinct names); the rig's calibration set is checked later
            parse_study_config(
                {"rig": "hst_trailer", "parameters": list(parameters), **paths}, folder
            )
        except (ValueError, TypeError) as error:
            raise _flag_error(arguments["parameters"], "parameters", error) from None
        mapping["parameters"] = list(parameters)
    where = f"{path}: " if path.is_file() else ""
    try:
        config = parse_study_config({**mapping, **paths}, folder)
    except (ValueError, TypeError) as error:
        raise MonitorError(f"{where}{error}") from None
    try:
        config = with_budget(config, budget, arguments["budget"])
    except ValueError as error:
        raise MonitorError(str(error)) from None
    if allow_small_budget:
        config = dataclasses.replace(
            config, budget=dataclasses.replace(config.budget, allow_small=True)
        )
    if workers is not None or scheduler is not None:
        try:
            config = dataclasses.replace(
                config, executor=ExecutorConfig(workers=workers, scheduler=scheduler)
            )
        except (ValueError, TypeError) as error:
            flag = arguments["workers"] if scheduler is None else arguments["scheduler"]
            raise MonitorError(f"{flag}: {error}") from None
    return config


def campaign_config(base: StudyConfig, campaign: Campaign, out: Path) -> StudyConfig:
    """The study config of one campaign: its runs in, ``out/<vehicle>/<date>`` out."""
    return dataclasses.replace(base, data=campaign.folder, out=out / campaign.campaign_id)


def campaign_status(folder: Path) -> str:
    """``finished`` (result and draws written), ``interrupted`` (a store only) or ``new``."""
    if (folder / RESULT_NAME).is_file() and (folder / SAMPLES_NAME).is_file():
        return "finished"
    if (folder / STORE_NAME).is_file():
        return "interrupted"
    return "new"


def _say(progress: bool, text: str) -> None:
    if progress:
        print(f"susp-bo monitor: {text}", file=sys.stderr)


def _refuse_orphaned_results(folder: Path, out: Path, expected: Sequence[Path]) -> None:
    """Refuse a results folder holding finished campaigns that ``folder`` no longer has.

    The maintenance table is rebuilt from the campaigns found: a campaign folder gone
    missing (an unmounted disk, an archived folder) would silently drop its result, and
    clear an alarm it raised.

    Raises:
        MonitorError: naming the results and what to do; nothing is changed.
    """
    known = {Path(p).resolve() for p in expected}
    orphans = sorted(
        path.parent
        for path in out.glob(f"*/*/{RESULT_NAME}")
        if path.is_file() and path.parent.resolve() not in known
    )
    if orphans:
        listed = ", ".join(str(p.relative_to(out)) for p in orphans[:5])
        more = f" and {len(orphans) - 5} more" if len(orphans) > 5 else ""
        raise MonitorError(
            f"{out} holds finished campaign results whose campaign folders are no longer in "
            f"{folder}: {listed}{more}; the maintenance table would silently drop them (and "
            "an alarm they raised). Restore those campaign folders, or move their results "
            f"out of {out} if the campaigns were withdrawn (nothing was changed)"
        )


def monitor(
    folder: str | Path,
    out: str | Path,
    *,
    rig: str | None = None,
    parameters: Sequence[str] | None = None,
    budget: int | None = None,
    warm_budget: int | None = None,
    workers: int | None = None,
    scheduler: str | None = None,
    threshold: float = ALARM_THRESHOLD,
    allow_small_budget: bool = False,
    figures: bool = True,
    progress: bool = True,
    warm_start: bool = True,
    argument_names: Mapping[str, str] = API_NAMES,
) -> dict[str, Any]:
    """Calibrate every campaign in ``folder`` (resumably), then write ``monitor.json`` and figures.

    Args:
        folder: monitoring folder (campaign sub-folders, optional ``monitor.toml``).
        out: results folder; ``out/<vehicle>/<date>/`` per campaign.
        rig: rig name or path (default: ``monitor.toml``'s, else ``hst_trailer``).
        parameters: calibrated subset of the rig's calibration set (default: all).
        budget: likelihood evaluations per campaign.
        warm_budget: likelihood evaluations of a campaign that starts warm (None: ``budget``).
            A calibration that stops early spends the rest of its budget auditing C_w, so a
            warm start saves simulations only through a smaller budget; it is checked
            against the minimum for q like ``budget``, and the verdict is computed as for
            any campaign.
        workers: local worker processes for the simulator runs (0 = in-process).
        scheduler: Dask scheduler address instead of workers.
        threshold: alarm when P(outside) > threshold on a trusted calibration.
        allow_small_budget: run campaigns whose budget is below the minimum for q
            parameters (refused otherwise, before any simulation); their calibrations are
            then not trusted and never raise or clear an alarm.
        figures: write the trend figures.
        progress: progress lines on stderr.
        warm_start: start each campaign of a vehicle from its previous campaign's posterior
            when that calibration was trusted (:func:`~susp_bo.monitoring.warm_start.
            plan_warm_start`: the design moves, the prior stays C_w); False = every
            campaign from the space-filling design.
        argument_names: how errors name ``rig``, ``parameters``, ``budget``,
            ``warm_budget``, ``workers``, ``scheduler`` and ``out``: :data:`API_NAMES` (the
            keywords) or :data:`CLI_NAMES` (the flags of ``susp-bo monitor``).

    Returns:
        The ``monitor.json`` payload.

    Raises:
        MonitorError: bad folder, settings or campaign data — before any simulation.
    """
    if isinstance(threshold, bool) or not isinstance(threshold, numbers.Real):
        raise MonitorError(
            f"threshold: {threshold!r} ({type(threshold).__name__}) is not allowed; expected "
            "a probability in (0, 1)"
        )
    if not 0.0 < threshold < 1.0:  # also false for nan
        raise MonitorError(f"threshold: got {threshold}; expected a probability in (0, 1)")
    folder, out = Path(folder).resolve(), Path(out).resolve()
    try:
        campaigns = discover_campaigns(folder)
    except CampaignError as error:
        raise MonitorError(str(error)) from None
    base = base_config(
        folder,
        out,
        rig=rig,
        parameters=parameters,
        budget=budget,
        workers=workers,
        scheduler=scheduler,
        allow_small_budget=allow_small_budget,
        arguments=argument_names,
    )
    spec, names = _rig_and_names(
        base, folder, rig=rig, parameters=parameters, arguments=argument_names
    )
    configs = {c.campaign_id: campaign_config(base, c, out) for c in campaigns}
    status = {c.campaign_id: campaign_status(configs[c.campaign_id].out) for c in campaigns}
    try:  # the warm campaigns' budget: the shared config with that many evaluations
        warm = with_budget(base, warm_budget, argument_names["warm_budget"])
    except ValueError as error:
        raise MonitorError(str(error)) from None
    if any(state != "finished" for state in status.values()):  # one budget, refused once
        problem = small_budget_problem(
            base, len(names), budget is not None, argument_names, folder / MONITOR_CONFIG_NAME
        )
        if problem is None and warm_start and warm_budget is not None:
            warm_names = {**argument_names, "budget": argument_names["warm_budget"]}
            path = folder / MONITOR_CONFIG_NAME
            problem = small_budget_problem(warm, len(names), True, warm_names, path)
        if problem is not None:
            raise MonitorError(problem)
    _refuse_orphaned_results(folder, out, [configs[c.campaign_id].out for c in campaigns])
    try:  # monitor.json or a trend figure blocked by a folder: said now, not after every campaign
        trends = tuple(f"trend_{n}.png" for n in names) if figures else ()
        check_output_files(out, (MONITOR_NAME, *trends), argument_names["out"])
    except ValueError as error:
        raise MonitorError(str(error)) from None
    bounds: dict[str, np.ndarray] = {}  # C_w of every campaign still to calibrate
    for campaign in campaigns:  # every input checked before the first simulation
        try:  # a campaign folder another process writes into: said now, not hours later
            refuse_if_busy(configs[campaign.campaign_id].out)
        except OutputFolderBusy as error:
            raise MonitorError(f"campaign {campaign.campaign_id}: {error}") from None
        try:
            bounds[campaign.campaign_id] = check_campaign(
                configs[campaign.campaign_id], campaign, status[campaign.campaign_id], names
            )
        except (StudyError, CampaignResultError) as error:
            raise MonitorError(
                f"campaign {campaign.campaign_id} ({campaign.folder}): {error}"
            ) from None
    out.mkdir(parents=True, exist_ok=True)
    _say(
        progress,
        f"{len(campaigns)} campaigns of {len({c.vehicle for c in campaigns})} vehicles: "
        + ", ".join(
            f"{s} {list(status.values()).count(s)}" for s in ("finished", "interrupted", "new")
        ),
    )
    previous: dict[str, Campaign] = {}  # vehicle -> its latest campaign so far
    for campaign in campaigns:  # sorted by vehicle, then date
        cid = campaign.campaign_id
        before = previous.get(campaign.vehicle)
        previous[campaign.vehicle] = campaign
        if status[cid] == "finished":
            continue
        start = None
        if warm_start and before is not None:
            start = plan_warm_start(
                configs[before.campaign_id].out,
                before.campaign_id,
                names,
                bounds[cid],
                warm.budget.initial_design,
                configs[cid].seeds.calibration,
                local_phase=configs[cid].search.local,
            )
        if start is not None:  # a warm campaign runs on the warm budget
            configs[cid] = dataclasses.replace(configs[cid], budget=warm.budget)
        how = f"warm start from {start.source}" if start is not None else "cold start"
        _say(progress, f"calibrating {cid} ({status[cid]}, {campaign.n_runs} runs, {how})")
        try:
            run_study(
                configs[cid],
                resume=status[cid] == "interrupted",
                progress=progress,
                design=None if start is None else start.design,
                design_note=None if start is None else start.to_dict(),
                local_after_design=start is not None,
            )
        except StudyError as error:
            raise MonitorError(f"campaign {cid}: {error}") from None
    payload = build_report(campaigns, configs, status, spec, names, threshold)
    write_json(out / MONITOR_NAME, payload)
    if figures:
        from susp_bo.monitoring.figures import trend_figures

        paths = trend_figures(payload, out)
        payload["figures"] = [p.name for p in paths]
        write_json(out / MONITOR_NAME, payload)
    _say(progress, f"wrote {out / MONITOR_NAME}")
    return payload


def _rig_and_names(
    base: StudyConfig,
    folder: Path,
    *,
    rig: str | None,
    parameters: Sequence[str] | None,
    arguments: Mapping[str, str] = CLI_NAMES,
) -> tuple[Any, tuple[str, ...]]:
    """The rig and the calibrated names; an error names the flag or file that gave them."""
    path = folder / MONITOR_CONFIG_NAME
    in_file = f"{path}: " if path.is_file() else ""
    try:
        spec = load_rig_spec(base.rig)
    except (FileNotFoundError, ValueError) as error:
        where = f"{arguments['rig']}: " if rig is not None else in_file
        raise MonitorError(f"{where}{error}") from None
    try:
        names = base.check_parameters(spec.calibration_names)
    except ValueError as error:
        if parameters is not None:
            raise _flag_error(arguments["parameters"], "parameters", error) from None
        raise MonitorError(f"{in_file}{error}") from None
    return spec, tuple(names)


def build_report(
    campaigns: Sequence[Campaign],
    configs: dict[str, StudyConfig],
    status: dict[str, str],
    spec: Any,
    names: Sequence[str],
    threshold: float = ALARM_THRESHOLD,
) -> dict[str, Any]:
    """The ``monitor.json`` payload from the campaigns' result folders."""
    parameters = {c.name: c for c in spec.calibration if c.name in names}
    acceptable = {name: parameters[name].acceptable for name in names}
    records: list[CampaignRecord] = []
    extra: dict[str, dict[str, Any]] = {}
    for campaign in campaigns:
        cid = campaign.campaign_id
        folder = configs[cid].out
        result, samples = read_finished(folder, names, [parameters[n].unit for n in names])
        trusted, why = trust(result)
        summaries = {
            name: summarise_parameter(name, samples[:, k], acceptable[name])
            for k, name in enumerate(result["parameters"])
        }
        records.append(
            CampaignRecord(
                cid,
                campaign.vehicle,
                campaign.date.isoformat(),
                trusted,
                why,
                summaries,
                campaign.truth,
            )
        )
        extra[cid] = {
            **campaign.to_dict(),
            "result_folder": cid,
            "status_before_this_run": status[cid],
            "trusted": trusted,
            "reliability": result.get("reliability"),
            "why": why,
            "n_simulations": result.get("n_simulations"),
            "n_evaluations": result.get("n_evaluations"),
            "budget": ((result.get("reliability") or {}).get("evidence") or {}).get("budget"),
            "warm_start": result.get("warm_start"),
            "n_draws": int(samples.shape[0]),
        }
    states = apply_alarms(records, acceptable, threshold)
    rows = []
    for record in records:
        row = dict(extra[record.campaign_id])
        row["parameters"] = {n: s.to_dict() for n, s in states[record.campaign_id].items()}
        if not record.trusted:
            row["alarm_note"] = f"not used for alarms: {record.why}"
        rows.append(row)
    descriptions = {name: parameters[name].description or name for name in names}
    return json_ready(
        {
            "rig": spec.name,
            "parameters": list(names),
            "units": [parameters[name].unit for name in names],
            "bounds": [[parameters[n].lower, parameters[n].upper] for n in names],
            "nominal": [parameters[n].reference for n in names],
            "acceptable": [None if acceptable[n] is None else list(acceptable[n]) for n in names],
            "descriptions": [descriptions[n] for n in names],
            "alarm_threshold": threshold,
            "alarm_rule": (
                f"alarm when P(outside the acceptable domain) > {threshold} on a trusted "
                "calibration; a calibration that is not trusted never raises or clears an alarm"
            ),
            "vehicles": sorted({c.vehicle for c in campaigns}),
            "campaigns": rows,
            "maintenance": maintenance_table(records, states, descriptions),
            "attention": attention_table(records, states),
            "n_simulations": int(sum(r.get("n_simulations") or 0 for r in rows)),
            "version": __version__,
        }
    )
