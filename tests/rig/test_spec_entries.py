"""The entries of a rig spec check themselves when built, naming the entry, the value and
what is allowed (:mod:`susp_bo.rig.spec_entries`)."""

from __future__ import annotations

import numpy as np
import pytest

from susp_bo.rig import spec
from susp_bo.rig.spec_entries import (
    CalibrationParameter,
    SensorSpec,
    SimulationSettings,
    check_parameter_value,
    require_number,
)


def test_sign_rules_follow_the_parameter_names_meaning() -> None:
    check_parameter_value("carbody_mass", 1.0)
    check_parameter_value("primary_vertical_damping", 0.0)
    check_parameter_value("yaw_damper_damping@bogie_front_left", 0.0)
    with pytest.raises(ValueError, match=r"parameter carbody_mass: got 0\.0; must be > 0"):
        check_parameter_value("carbody_mass", 0.0)
    with pytest.raises(ValueError, match="must be >= 0"):
        check_parameter_value("yaw_damper_damping@bogie_front_left", -1.0)
    with pytest.raises(ValueError, match="must be finite"):
        check_parameter_value("rig_anything", float("nan"))


def test_an_admissible_interval_holds_only_physical_values() -> None:
    # a negative stiffness in C_w was simulated (and failed) instead of being refused
    with pytest.raises(
        ValueError,
        match=r"parameter primary_vertical_stiffness\.lower: .*got -1000000\.0; must be >= 0",
    ):
        CalibrationParameter("primary_vertical_stiffness", -1.0e6, 1.7e6, 1.0e6)
    with pytest.raises(ValueError, match=r"parameter carbody_mass\.lower: .*must be > 0"):
        CalibrationParameter("carbody_mass", 0.0, 5.0e4, 3.0e4)
    CalibrationParameter("primary_vertical_damping", 0.0, 2.0e4, 1.0e4)  # 0 is physical
    CalibrationParameter("carbody_bending_frequency_hz", -1.0, 12.0, 9.0)  # no sign rule


def test_require_number_refuses_booleans_and_strings_by_name() -> None:
    assert require_number("x", 3) == 3.0
    with pytest.raises(ValueError, match=r"\[bogie\] mass: got True; must be a number"):
        require_number("[bogie] mass", True)
    with pytest.raises(ValueError, match="got '1'"):
        require_number("where", "1")


def test_sensor_direction_and_position_are_checked() -> None:
    sensor = SensorSpec("carbody_front_vertical", "carbody", (9, 0, 2), "vertical")
    assert sensor.position_m == (9.0, 0.0, 2.0)
    with pytest.raises(ValueError, match="direction: got 'longitudinal'; allowed vertical, lat"):
        SensorSpec("s", "carbody", (0, 0, 0), "longitudinal")
    with pytest.raises(ValueError, match="need 3 finite numbers"):
        SensorSpec("s", "carbody", (0, 0, float("inf")), "lateral")


def test_simulation_settings_ranges_and_the_sampling_ratio() -> None:
    settings = SimulationSettings(time_step_s=0.001, sample_rate_hz=200.0)
    assert settings.steps_per_sample == 5
    with pytest.raises(ValueError, match=r"time_step_s: got 0.02; allowed range \(0, 0.01\] s"):
        SimulationSettings(time_step_s=0.02)
    with pytest.raises(ValueError, match="integer multiple"):
        SimulationSettings(time_step_s=0.002, sample_rate_hz=300.0)
    with pytest.raises(ValueError, match="track_quality: got 'medium'"):
        SimulationSettings(track_quality="medium")


def test_outside_acceptable_marks_values_beyond_the_maintenance_limits() -> None:
    damper = CalibrationParameter(
        "yaw_damper_damping", 1e6, 8e6, 4e6, "N*s/m", "yaw damper", acceptable=(2e6, 6e6)
    )
    flags = damper.outside_acceptable(np.array([1.5e6, 4e6, 6.5e6]))
    assert flags.tolist() == [True, False, True]


def test_the_spec_module_still_exports_its_entries() -> None:
    assert spec.CalibrationParameter is CalibrationParameter
    assert spec.SimulationSettings is SimulationSettings and spec.SensorSpec is SensorSpec
