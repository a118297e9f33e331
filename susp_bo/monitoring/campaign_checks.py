"""The checks of ``susp-bo monitor`` before its first simulation: the shared budget and each
campaign's inputs, stored evaluations and finished result.

The budget is one for every campaign, so a budget below the minimum for q is refused once,
naming what set it — the ``budget`` keyword of :func:`susp_bo.monitor`, ``--budget`` of
``susp-bo monitor``, or ``monitor.toml`` — and how to run anyway in the same terms
(``allow_small_budget=True``, ``--allow-small-budget``, ``[budget] allow_small = true``),
not as a study file's keys blamed on the first campaign.
"""

from __future__ import annotations

import dataclasses
import numbers
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from susp_bo.calibration.budget import budget_message, budget_requirement, design_for_budget
from susp_bo.calibration.study_preparation import STORE_NAME, check_results_folder, prepare_study
from susp_bo.monitoring.campaign_results import check_campaign_store, read_finished
from susp_bo.monitoring.campaigns import Campaign
from susp_bo.study_config import StudyConfig


def with_budget(config: StudyConfig, budget: int | None, flag: str) -> StudyConfig:
    """``config`` with ``budget`` likelihood evaluations (the design cut to fit it, as
    :func:`~susp_bo.calibration.budget.design_for_budget` does); unchanged for None.

    Raises:
        ValueError: ``budget`` not an integer >= 2, or one the config refuses; the message
            names ``flag``.
    """
    if budget is None:
        return config
    if isinstance(budget, bool) or not isinstance(budget, numbers.Integral) or budget < 2:
        # checked first: the design size is cut to the budget and would be blamed
        raise ValueError(
            f"{flag}: {budget!r} is not allowed; expected an integer >= 2 "
            "(likelihood evaluations per campaign)"
        )
    try:
        return dataclasses.replace(
            config,
            budget=dataclasses.replace(
                config.budget,
                max_evaluations=int(budget),
                initial_design=design_for_budget(config, int(budget)),
            ),
        )
    except (ValueError, TypeError) as error:
        raise ValueError(f"{flag}: {error}") from None


def small_budget_problem(
    base: StudyConfig,
    q: int,
    budget_given: bool,
    arguments: Mapping[str, str],
    config_file: Path,
) -> str | None:
    """Why the campaigns' budget is refused (None where it is enough or allowed small).

    Args:
        base: the study config every campaign shares (:func:`~.runner.base_config`).
        q: number of calibrated parameters.
        budget_given: the budget came from the ``budget`` argument (else ``monitor.toml``
            or the default).
        arguments: how the arguments are named (``runner.API_NAMES`` or ``CLI_NAMES``).
        config_file: the monitoring folder's ``monitor.toml`` (named where it set the budget).
    """
    b = base.budget
    requirement = budget_requirement(q, b.initial_design, b.batch_size, b.check_points)
    if b.allow_small or b.max_evaluations >= requirement.minimum:
        return None
    flag = arguments["budget"]
    override = "--allow-small-budget" if flag.startswith("--") else "allow_small_budget=True"
    if budget_given:
        return budget_message(b.max_evaluations, requirement, flag, f"pass {override}")
    if config_file.is_file():
        where = f"{config_file}: [budget] max_evaluations = {b.max_evaluations}"
        advice = "set it to"
        allow = f"set [budget] allow_small = true there (or pass {override})"
    else:
        where, advice = f"the default budget ({b.max_evaluations})", f"pass {flag}"
        allow = f"pass {override}"
    return (
        f"{where} is below the minimum {requirement.describe()} of every "
        f"campaign still to calibrate: no room to refine the search and check the surrogate; "
        f"{advice} {requirement.minimum} or more, or {allow} to run anyway (the results are "
        "then marked not trusted)"
    )


def check_campaign(
    config: StudyConfig, campaign: Campaign, state: str, names: Sequence[str]
) -> np.ndarray:
    """Check one campaign before any simulation; its (2 x q) C_w.

    A new campaign: its inputs (:func:`prepare_study`). An interrupted one: also that its
    store belongs to the runs, rig and output error of now. A finished one: its result and
    draws are readable and of ``names``, and were computed on the runs now in its folder
    (:func:`~susp_bo.monitoring.campaign_results.check_campaign_store`).

    Raises:
        StudyError: bad inputs of the campaign.
        CampaignResultError: a stale or damaged results folder (nothing is changed).
    """
    if state == "finished":
        # the budget plays no part in a finished result: only its data are compared
        config = dataclasses.replace(
            config, budget=dataclasses.replace(config.budget, allow_small=True)
        )
    study = prepare_study(config, resume=(config.out / STORE_NAME).exists())
    if state == "finished":  # readable, of these parameters, in the units the rig gives now
        read_finished(config.out, names, study.units)
    else:  # what run_study would refuse on this campaign's turn: said before the first runs
        check_results_folder(config, resume=(config.out / STORE_NAME).exists())
    if state != "new":
        check_campaign_store(study, finished=state == "finished", campaign_folder=campaign.folder)
    return study.bounds
