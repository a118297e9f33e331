"""The effect library: each effect reaches both models, with the physics it claims."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from susp_bo.discrepancy.effects import EFFECTS, beam_mode_shape, with_effect, without_effects
from susp_bo.rig.assembly import build_assembly
from susp_bo.rig.effects import available_effects
from susp_bo.rig.linear import LinearisedRig
from susp_bo.rig.spec import RigSpec


def test_the_library_is_registered_with_the_rig() -> None:
    assert set(EFFECTS) <= set(available_effects())
    assert {"carbody_bending", "wheel_out_of_roundness", "yaw_damper_series_stiffness",
            "lateral_bump_stop", "air_spring_reservoir"} <= set(EFFECTS)  # fmt: skip


@pytest.mark.parametrize("name", sorted(EFFECTS))
def test_every_effect_changes_the_spectra_where_it_says(base_spec: RigSpec, name: str) -> None:
    effect = EFFECTS[name]
    speed = 83.33
    before = LinearisedRig(base_spec).spectra(speed_m_s=speed).log_amplitude
    after = LinearisedRig(with_effect(base_spec, name)).spectra(speed_m_s=speed).log_amplitude
    change = np.abs(after - before)
    shows = [all(word in c for word in effect.channels) for c in base_spec.channels]
    assert change[shows].max() > 0.3
    if name != "yaw_damper_series_stiffness":  # that one also pitches the carbody (docstring)
        assert change[shows].max() >= change[[not s for s in shows]].max()


def test_carbody_bending_adds_a_mode_at_its_frequency(base_spec: RigSpec) -> None:
    spec = with_effect(base_spec, "carbody_bending", {"frequency_hz": 11.0})
    modes = LinearisedRig(spec).modal_frequencies_hz()
    assert modes["carbody_bending"] == pytest.approx(11.0, rel=0.05)  # the suspension couples
    assembly = build_assembly(spec)
    assert "carbody_bending.eta" in assembly.dof_names
    # free-free mode shape: 1 mid-car, zero mean (orthogonal to bounce), nodes near 0.22 L
    x = np.linspace(-12.5, 12.5, 4001)
    shape = beam_mode_shape(x, 25.0)
    assert shape[2000] == pytest.approx(1.0)
    assert abs(np.mean(shape)) < 1e-3
    assert beam_mode_shape(0.5 * 25.0 - 0.224 * 25.0, 25.0) == pytest.approx(0.0, abs=0.01)


def test_wheel_out_of_roundness_is_a_line_at_n_v_over_pi_d(base_spec: RigSpec) -> None:
    speed, order = 55.56, 1
    spec = with_effect(base_spec, "wheel_out_of_roundness", {"order": order, "amplitude_m": 3e-4})
    lines = LinearisedRig(spec).periodic_lines(None, speed)
    diameter = 2 * spec.parameters["wheelset_rolling_radius"]
    assert lines[0][0] == pytest.approx(order * speed / (math.pi * diameter))
    channels = spec.channels
    power = lines[0][1]
    assert (
        power[channels.index("bogie_front_vertical")]
        > 10 * power[channels.index("bogie_rear_vertical")]
    )  # wheelset 1 is under the front bogie


def test_series_and_dead_band_effects_replace_the_base_elements(base_spec: RigSpec) -> None:
    yaw = build_assembly(with_effect(base_spec, "yaw_damper_series_stiffness", {"stiffness": 4e6}))
    assert np.allclose(yaw.series.stiffness, 4e6)
    stop = build_assembly(with_effect(base_spec, "lateral_bump_stop", {"gap_m": 0.001}))
    assert np.allclose(stop.dead_bands.gap[:2], 0.001)
    reservoir = build_assembly(with_effect(base_spec, "air_spring_reservoir"))
    names = [n for n in reservoir.series.group.names if n.startswith("air_spring")]
    assert len(names) == 4


def test_air_spring_stiffness_rises_above_the_corner(base_spec: RigSpec) -> None:
    spec = with_effect(base_spec, "air_spring_reservoir", {"stiffness_ratio": 2.0,
                                                           "corner_frequency_hz": 1.0})  # fmt: skip
    k = spec.parameters["secondary_vertical_stiffness"]
    k_r, c_r = 2.0 * k, 2.0 * k / (2 * math.pi * 1.0)
    for f, expected in ((0.01, k), (100.0, 3.0 * k)):
        w = 2j * math.pi * f
        dynamic = k + (k_r * c_r * w / (k_r + c_r * w)).real
        assert dynamic == pytest.approx(expected, rel=0.01)
    assembly = build_assembly(spec)
    pick = [n.startswith("air_spring") for n in assembly.series.group.names]
    assert np.allclose(assembly.series.stiffness[pick], k_r)
    assert np.allclose(assembly.series.damping[pick], c_r)


def _gas_column_stiffness(volume_m3: float, n: float, area_m2: float, p_pa: float) -> float:
    """Stiffness (N/m) of a gas column p V^n = const under a piston, by a central difference."""
    dx = 1e-6
    force = [area_m2 * p_pa * (volume_m3 / (volume_m3 - area_m2 * x)) ** n for x in (-dx, dx)]
    return (force[1] - force[0]) / (2 * dx)


@pytest.mark.parametrize("volume_ratio", [1.0, 2.0, 3.6])
def test_air_spring_ratio_range_covers_real_reservoir_volumes(volume_ratio: float) -> None:
    """Reservoirs of 1–3.6 bellows volumes (3.6: the best design of Gao et al. 2014)
    give stiffness ratios well inside the admissible range, not on its bound."""
    bellows, area, pressure = 0.05, 0.25, 5.0e5  # m³, m², Pa: a high-speed-train air spring
    for n in (1.0, 1.4):  # one polytropic index with the orifice open and shut
        k_open = _gas_column_stiffness(bellows * (1 + volume_ratio), n, area, pressure)
        k_shut = _gas_column_stiffness(bellows, n, area, pressure)
        ratio = (k_shut - k_open) / k_open
        assert ratio == pytest.approx(volume_ratio, rel=1e-4)  # the docstring's V_r / V_b
        (parameter,) = (p for p in EFFECTS["air_spring_reservoir"].parameters
                        if p.key == "stiffness_ratio")  # fmt: skip
        margin = 0.05 * (parameter.upper - parameter.lower)  # 5× the naming rule's 1 %
        assert parameter.lower + margin < ratio < parameter.upper - margin


def test_effect_parameters_are_named_validated_and_calibratable(base_spec: RigSpec) -> None:
    spec = with_effect(base_spec, "carbody_bending", {"frequency_hz": 8.0}, calibrate=True)
    assert spec.parameters["carbody_bending_frequency_hz"] == 8.0
    assert spec.calibration_names[-2:] == (
        "carbody_bending_frequency_hz",
        "carbody_bending_damping_ratio",
    )
    changed = spec.with_parameters({"carbody_bending_frequency_hz": 12.0})
    assert LinearisedRig(changed).modal_frequencies_hz()["carbody_bending"] > 11.0
    with pytest.raises(ValueError, match="outside the admissible"):
        build_assembly(spec.with_parameters({"carbody_bending_frequency_hz": 20.0}))
    with pytest.raises(ValueError, match="unknown parameter"):
        with_effect(base_spec, "carbody_bending", {"frequncy_hz": 8.0})
    with pytest.raises(ValueError, match="not in the library"):
        with_effect(base_spec, "carbody_twist")
    assert without_effects(spec).calibration_names == base_spec.calibration_names
    off = dataclasses.replace(spec, effects={"carbody_bending": {"enabled": False}})
    assert build_assembly(off).n_dofs == build_assembly(base_spec).n_dofs
