"""CalibrationSettings: every bad value is refused naming its field."""

from __future__ import annotations

import pytest

from susp_bo.calibration.settings import CalibrationSettings


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
