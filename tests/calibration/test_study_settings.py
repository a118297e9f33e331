"""The study config's sections reach the loop's settings, field by field."""

from __future__ import annotations

import dataclasses
from pathlib import Path

from susp_bo.calibration.basin_search import BasinSettings
from susp_bo.calibration.settings import CalibrationSettings
from susp_bo.calibration.study import calibration_settings
from susp_bo.study_config import BudgetConfig, SearchConfig, SeedsConfig, StudyConfig


def test_study_config_sections_reach_the_loop_settings() -> None:
    config = StudyConfig(
        rig="hst_trailer",
        data=Path("d"),
        out=Path("o"),
        budget=BudgetConfig(max_evaluations=90, initial_design=30, batch_size=6, check_points=4),
        seeds=SeedsConfig(calibration=5, mcmc=6),
        search=SearchConfig(local=True, basins=False, refine_optimism=2, kernel="auto"),
    )
    settings = calibration_settings(config)
    assert (settings.max_evaluations, settings.initial_design_size) == (90, 30)
    assert (settings.batch_size, settings.check_points) == (6, 4)
    assert (settings.seed, settings.mcmc_seed) == (5, 6)
    assert (settings.local_search, settings.basin_search) == (True, False)
    assert settings.refine_optimism == 2.0 and isinstance(settings.refine_optimism, float)
    assert settings.surrogate.kernel == "auto"
    assert settings.basin == BasinSettings()  # the API's default hunt (3) when omitted


def test_the_hunt_reaches_the_basin_phase_and_nothing_else_changes() -> None:
    base = StudyConfig(rig="hst_trailer", data=Path("d"), out=Path("o"))
    hunting = StudyConfig(rig="hst_trailer", data=Path("d"), out=Path("o"),
                          search=SearchConfig(hunt=5))  # fmt: skip
    settings = calibration_settings(hunting)
    assert settings.basin.hunt_beta == 5.0 and isinstance(settings.basin.hunt_beta, float)
    assert settings.basin == dataclasses.replace(BasinSettings(), hunt_beta=5.0)
    assert dataclasses.replace(settings, basin=BasinSettings()) == calibration_settings(base)
    assert calibration_settings(base).basin.hunt_beta == 3.0  # omitted: the default
    off = StudyConfig(rig="hst_trailer", data=Path("d"), out=Path("o"),
                      search=SearchConfig(hunt=0))  # fmt: skip
    assert calibration_settings(off).basin.hunt_beta == 0.0


def test_default_search_section_keeps_the_loop_default_refinement() -> None:
    config = StudyConfig(rig="hst_trailer", data=Path("d"), out=Path("o"))
    assert calibration_settings(config).refine_optimism == CalibrationSettings().refine_optimism
    assert calibration_settings(config).surrogate == CalibrationSettings().surrogate
    assert calibration_settings(config).basin == CalibrationSettings().basin
