"""The study config's sections, validated on construction (``susp_bo.study_sections``)."""

from __future__ import annotations

from pathlib import Path

import pytest

from susp_bo.study_config import load_study_config
from susp_bo.study_sections import (
    SECTIONS,
    BudgetConfig,
    ExecutorConfig,
    MCMCConfig,
    OutputErrorConfig,
    SearchConfig,
    SeedsConfig,
)


def test_sections_by_table_name_in_file_order() -> None:
    assert list(SECTIONS) == ["budget", "seeds", "executor", "mcmc", "output_error", "search"]
    for name, cls in SECTIONS.items():
        assert cls.section == name
        cls()  # every default is valid


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: BudgetConfig(max_evaluations=True), r"budget\.max_evaluations: True"),
        (lambda: BudgetConfig(initial_design=1), r"budget\.initial_design: 1 .* >= 2"),
        (lambda: BudgetConfig(max_evaluations=20, initial_design=30), r">= budget\.initial"),
        (lambda: BudgetConfig(allow_small="yes"), r"budget\.allow_small: 'yes'.*true or false"),
        (lambda: SeedsConfig(mcmc=-1), r"seeds\.mcmc: -1 .* >= 0"),
        (lambda: ExecutorConfig(workers=2, scheduler="tcp://h:8786"), r"not allowed together"),
        (lambda: ExecutorConfig(scheduler=""), r"executor\.scheduler: ''"),
        (lambda: ExecutorConfig(scheduler="host"), r"executor\.scheduler: 'host'.*no port"),
        (lambda: MCMCConfig(chains=0), r"mcmc\.chains: 0 is not allowed"),
        (lambda: MCMCConfig(sampler="nuts"), r'"random_walk", "hmc", "auto"'),
        (lambda: MCMCConfig(draws=2), r"mcmc\.draws: 2 .* >= 8 .*HMC keeps half"),
        (lambda: MCMCConfig(draws=7, sampler="hmc"), r"mcmc\.draws: 7 .* >= 8"),
        (lambda: MCMCConfig(draws=3, sampler="random_walk"), r"mcmc\.draws: 3 .* >= 4"),
        (lambda: MCMCConfig(draws=200.0), r"mcmc\.draws: 200\.0 is not allowed"),
        # session 29's probe: sizes that fail with a MemoryError after every simulation
        (lambda: MCMCConfig(chains=10**12), r"= 2,500,000,000,000,000 chain steps .* 1,280,000;"),
        (lambda: MCMCConfig(chains=40_001), r"40001 x \(500 \+ 2000\) = 100,002,500 chain"),
        (lambda: BudgetConfig(max_evaluations=10**12), r"max_evaluations: 1000000000000 .* 100000"),
        (lambda: SearchConfig(kernel="rbf"), r'"matern", "additive_pairs", "auto"'),
        (lambda: OutputErrorConfig(model="mixture"), r"output_error\.model"),
    ],
)
def test_a_bad_value_names_the_field_the_value_and_what_is_allowed(make, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        make()


def test_the_largest_sizes_a_study_accepts_are_accepted() -> None:
    assert MCMCConfig(chains=40_000).chains == 40_000  # 10⁸ chain steps exactly
    assert BudgetConfig(max_evaluations=100_000).max_evaluations == 100_000


def test_paired_config_refuses_a_correlation_length() -> None:
    with pytest.raises(ValueError, match=r"correlation_length_hz.*unpaired"):
        OutputErrorConfig(model="paired", correlation_length_hz=0.5)
    assert OutputErrorConfig(model="unpaired", correlation_length_hz=0.5).model == "unpaired"


@pytest.mark.parametrize("sampler", ["random_walk", "hmc", "auto"])
def test_mcmc_draws_minimum_agrees_with_the_calibration_settings(sampler: str) -> None:
    """``[mcmc] draws`` is refused when the config is read, as CalibrationSettings refuses
    ``mcmc_samples``, not after the whole budget in Pyro's split R-hat."""
    from susp_bo.calibration.settings import min_mcmc_samples

    least = min_mcmc_samples(sampler)
    assert MCMCConfig(draws=least, sampler=sampler).draws == least
    with pytest.raises(ValueError, match=r"mcmc\.draws"):
        MCMCConfig(draws=least - 1, sampler=sampler)


def test_a_study_file_with_too_few_draws_is_refused_naming_the_key(tmp_path: Path) -> None:
    path = tmp_path / "study.toml"
    path.write_text('rig = "hst_trailer"\ndata = "data"\nout = "out"\n\n[mcmc]\ndraws = 2\n')
    with pytest.raises(ValueError, match=r"study\.toml.*mcmc\.draws: 2 is not allowed"):
        load_study_config(path)
