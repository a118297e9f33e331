"""The study config's sections reach the loop's settings, field by field."""

from __future__ import annotations

import dataclasses
import tomllib
from pathlib import Path

import pytest

from susp_bo.calibration.basin_search import BasinSettings
from susp_bo.calibration.settings import CalibrationSettings
from susp_bo.calibration.study import calibration_settings, config_as_run
from susp_bo.study_config import (
    BudgetConfig,
    SearchConfig,
    SeedsConfig,
    StudyConfig,
    parse_study_config,
)


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


@pytest.mark.parametrize(
    ("search", "written"),
    [({}, 3.0), ({"local": True}, 0.0), ({"basins": False}, 0.0), ({"hunt": 5}, 5.0),
     ({"local": True, "hunt": 0}, 0.0)],
)  # fmt: skip
def test_the_results_folder_records_the_hunt_the_run_used(
    search: dict, written: float, tmp_path: Path
) -> None:
    """An omitted hunt is written out as the run used it (reviewer, session 43), and the
    written config loads back with the same settings."""
    config = StudyConfig(rig="hst_trailer", data=tmp_path, out=tmp_path / "o",
                         search=SearchConfig(**search))  # fmt: skip
    ran = config_as_run(config)
    assert ran.search.hunt == written
    assert dataclasses.replace(ran.search, hunt=config.search.hunt) == config.search
    again = parse_study_config(tomllib.loads(ran.to_toml()), Path.cwd())
    assert again.search == ran.search
    assert calibration_settings(ran).basin.hunt_beta == written
