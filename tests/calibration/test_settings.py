"""CalibrationSettings: every bad value is refused naming its field."""

from __future__ import annotations

import numpy as np
import pytest

from susp_bo.calibration.settings import CalibrationSettings, min_mcmc_samples
from susp_bo.calibration.surrogate import SurrogateSettings


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("batch_size", 0),
        ("max_evaluations", 1),
        ("ei_tolerance", 0.0),
        ("estimator", "max"),
        ("max_ego_fraction", 1.5),
        ("mcmc_backend", "numpyro"),
        ("num_threads", 0),
        ("check_points", -1),
        ("check_points", 2.5),
        ("check_tolerance", 0.0),
        ("mcmc_warmup", -1),
        ("design_method", "grid"),
    ],
)
def test_settings_validation_names_the_field(field: str, value: object) -> None:
    with pytest.raises(ValueError, match=field):
        CalibrationSettings(**{field: value})


def test_defaults_are_valid_and_sample_a_million_draws() -> None:
    s = CalibrationSettings()
    assert s.mcmc_chains * s.mcmc_samples >= 1_000_000 and s.check_points == 8


INTEGER_FIELDS = (
    "seed",
    "mcmc_seed",
    "batch_size",
    "max_evaluations",
    "initial_design_size",
    "check_points",
    "mcmc_chains",
    "mcmc_warmup",
    "mcmc_samples",
    "candidate_count",
    "acquisition_restarts",
    "acquisition_raw_samples",
    "num_threads",
)


@pytest.mark.parametrize("field", INTEGER_FIELDS)
@pytest.mark.parametrize("value", [16.0, 2.5, True, "16"])
def test_integer_fields_refuse_floats_and_bools_naming_the_field(field: str, value: object) -> None:
    """An integral float (16.0) used to pass the check and crash in torch or numpy once
    the whole budget was spent; no silent conversion either."""
    with pytest.raises(ValueError, match=rf"^{field}: {value!r} \({type(value).__name__}\)"):
        CalibrationSettings(**{field: value})


def test_numpy_integers_are_integers() -> None:
    s = CalibrationSettings(seed=np.int64(3), mcmc_samples=np.int32(100), max_evaluations=None)
    assert s.seed == 3 and s.mcmc_samples == 100


@pytest.mark.parametrize(
    ("field", "value", "allowed"),
    [
        ("seed", -1, "an integer >= 0"),
        ("seed", None, "an integer >= 0"),
        ("mcmc_seed", -3, "None or an integer >= 0"),
    ],
)
def test_seeds_must_be_non_negative_integers(field: str, value: object, allowed: str) -> None:
    with pytest.raises(ValueError, match=rf"^{field}: {value!r}.*expected {allowed}"):
        CalibrationSettings(**{field: value})


@pytest.mark.parametrize(("sampler", "least"), [("random_walk", 4), ("hmc", 8), ("auto", 8)])
def test_mcmc_samples_leave_four_draws_per_chain_for_the_split_r_hat(
    sampler: str, least: int
) -> None:
    """HMC (forced, or run by "auto") keeps mcmc_samples // 2 draws per chain; fewer than 4
    crashed in Pyro's split R-hat after the whole budget."""
    assert min_mcmc_samples(sampler) == least
    assert CalibrationSettings(mcmc_samples=least, mcmc_sampler=sampler).mcmc_samples == least
    with pytest.raises(ValueError, match=rf"mcmc_samples: {least - 1} .* >= {least} .*R-hat"):
        CalibrationSettings(mcmc_samples=least - 1, mcmc_sampler=sampler)


def test_a_global_fixed_noise_search_is_unboxed_unlocal_and_noiseless() -> None:
    """The condition under which the kernel switch and the modes' optimism may act."""
    assert CalibrationSettings().global_fixed_noise_search(local_phase=False)
    assert not CalibrationSettings().global_fixed_noise_search(local_phase=True)
    assert not CalibrationSettings(trust_region=True).global_fixed_noise_search(False)
    learned = CalibrationSettings(surrogate=SurrogateSettings(noise="learned"))
    assert not learned.global_fixed_noise_search(False)
