"""Steady curving against independent results: V²/R − gφ, roll-out, pure rolling, flange contact."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from susp_bo.rig.assembly import build_assembly, free_wheelset_assembly
from susp_bo.rig.curving import design_inputs, steady_state
from susp_bo.rig.design import GRAVITY_M_S2, RAIL_CENTRES_M, DesignError, balancing_cant_m
from susp_bo.rig.dynamics import ForceModel
from susp_bo.rig.line_file import design_from_segments
from susp_bo.rig.linear import LinearisedRig
from susp_bo.rig.linear_curving import LinearModelNotApplicable
from susp_bo.rig.simulator import Rig, RigResponse, _design_start, integrate
from susp_bo.rig.spec import RigSpec
from susp_bo.rig.track import AxleExcitation, SpeedProfile, TrackGeometry
from susp_bo.rig.world import VehicleWorld

DB = 20.0 / math.log(10.0)


def _line(radius_m: float, cant_mm: float, speed: float, seconds: float, tangent_m: float = 100.0):
    return design_from_segments(
        [
            {"type": "tangent", "length_m": tangent_m},
            {"type": "transition", "length_m": 200.0},
            {
                "type": "curve",
                "length_m": speed * seconds + 100.0,
                "radius_m": radius_m,
                "cant_mm": cant_mm,
                "direction": "left",
            },
        ]
    )


def _smooth_track(length_m: float) -> TrackGeometry:
    zeros = np.zeros(int(length_m / 0.25) + 2)
    return TrackGeometry(0.25, zeros, zeros, zeros, zeros)


def _hand_roll_per_lateral_acceleration(p: dict[str, float]) -> float:
    """Carbody roll (rad) per m/s² of lateral load: bogies on the primaries + carbody on the
    secondaries (roll about the secondary lateral spring level), written independently of
    the rig's element rows."""
    primary_roll = 8 * p["primary_vertical_stiffness"] * p["primary_lateral_half_spacing"] ** 2
    overturning = p["carbody_mass"] * (p["carbody_cg_height"] - p["primary_height"]) + 2 * p[
        "bogie_mass"
    ] * (p["bogie_cg_height"] - p["primary_height"])
    secondary_roll = (
        4 * p["secondary_vertical_stiffness"] * p["secondary_lateral_half_spacing"] ** 2
        + 2 * p["anti_roll_bar_stiffness"]
    )
    lever = p["carbody_cg_height"] - p["secondary_height"]
    return overturning / primary_roll + p["carbody_mass"] * lever / secondary_roll


@pytest.fixture(scope="module")
def curve_run(reference_spec: RigSpec) -> tuple[RigSpec, RigResponse, float]:
    """The car entering a steady left-hand curve (R 5000 m, 60 mm cant) on smooth track."""
    spec = reference_spec.with_simulation(duration_s=20.0, warm_up_s=2.0)
    speed = spec.simulation.speed_m_s
    design = _line(5000.0, 60.0, speed, 22.0)
    with Rig(spec) as rig:
        response = rig.simulate(_smooth_track(speed * 22.0 + 40.0), design=design)
    return spec, response, speed


def test_quasi_static_carbody_lateral_acceleration_is_v2_over_r_minus_g_phi(
    curve_run: tuple[RigSpec, RigResponse, float],
) -> None:
    spec, response, speed = curve_run
    # the car is in the full curve after ~4 s; a slow carbody sway on the closed bump stops
    # (period ≈ 4 s) decays by then; average over its last period
    steady = response.time_s > 18.0
    uncompensated = speed**2 / 5000.0 - GRAVITY_M_S2 * 0.060 / RAIL_CENTRES_M  # V²/R − g φ
    # the floor accelerometers also see gravity through the carbody's roll-out in the curve
    roll = _hand_roll_per_lateral_acceleration(spec.parameters) * uncompensated
    for channel in ("carbody_front_lateral", "carbody_mid_lateral", "carbody_rear_lateral"):
        reading = float(np.mean(response.channel(channel)[steady]))
        track_plane = reading - GRAVITY_M_S2 * roll
        assert track_plane == pytest.approx(uncompensated, rel=0.02), channel
    # the roll-out coefficient itself (≈ 0.11 here) against the hand calculation
    roll_out = np.mean(response.channel("carbody_mid_lateral")[steady]) / uncompensated - 1.0
    assert roll_out == pytest.approx(GRAVITY_M_S2 * roll / uncompensated, rel=0.02)
    # the dynamic run settles on the quasi-static state of the linearised rig (bump stops on)
    state = LinearisedRig(spec).steady_curving(5000.0, 0.060)
    for channel in spec.channels:
        assert np.mean(response.channel(channel)[steady]) == pytest.approx(
            state["sensors"][channel], rel=1e-3, abs=1e-4
        ), channel
    assert abs(state["dead_bands"]["bump_stop_bogie_front"]) > 0.020  # the stop is closed


def test_no_cant_deficiency_no_quasi_static_lateral_acceleration(reference_spec: RigSpec) -> None:
    spec = reference_spec.with_simulation(duration_s=10.0, warm_up_s=2.0)
    speed = spec.simulation.speed_m_s
    cant = balancing_cant_m(7000.0, speed)
    with Rig(spec) as rig:
        response = rig.simulate(
            _smooth_track(speed * 12.0 + 40.0), design=_line(7000.0, cant * 1000, speed, 12.0)
        )
    steady = response.time_s > 8.0
    centripetal = speed**2 / 7000.0  # ≈ 1 m/s²
    for channel in spec.channels:
        if channel.endswith("lateral"):
            assert abs(np.mean(response.channel(channel)[steady])) < 2e-3 * centripetal, channel


def test_a_free_wheelset_curves_at_the_pure_rolling_offset_in_pybullet(
    reference_spec: RigSpec,
) -> None:
    p = reference_spec.parameters
    radius, speed, dt, steps = 2000.0, 10.0, 5e-4, 12000
    pure = (
        p["wheelset_rolling_radius"]
        * p["contact_half_contact_spacing"]
        / (p["contact_equivalent_conicity"] * radius)
    )  # r0 b / (λ R), outwards (to the right in a left-hand curve)
    assembly = free_wheelset_assembly(reference_spec)
    design = design_from_segments(
        [
            {"type": "tangent", "length_m": 5.0},
            {"type": "transition", "length_m": 20.0},
            {"type": "curve", "length_m": 100.0, "radius_m": radius, "direction": "left"},
        ]
    )
    t = np.arange(steps + 1) * dt
    terms = design_inputs(assembly, design, 1.0 + speed * t, np.full(t.size, speed), dt)
    zeros = np.zeros((1, steps + 1))
    world = VehicleWorld(dt)
    try:
        world.build(assembly)
        q, _ = integrate(
            world,
            ForceModel(assembly),
            AxleExcitation(t, *([zeros] * 7)),
            np.full(t.size, speed),
            1,
            0.2,
            assembly.dof_names,
            terms,
        )
    finally:
        world.close()
    # Klingel oscillation about the new equilibrium; its mean over the curve is the offset
    assert np.mean(q[t > 4.0, 0]) == pytest.approx(-pure, rel=0.02)
    q_static, _ = steady_state(assembly, terms.offsets[-1], terms.loads[-1])
    assert q_static[0] == pytest.approx(-pure, rel=1e-9)


def test_wheelsets_of_the_car_take_pure_rolling_offsets_when_free_to_steer(
    reference_spec: RigSpec,
) -> None:
    p = dict(reference_spec.parameters)
    radius, speed = 20000.0, 20.0
    pure = (
        p["wheelset_rolling_radius"]
        * p["contact_half_contact_spacing"]
        / (p["contact_equivalent_conicity"] * radius)
    )
    free = dict(p, primary_longitudinal_stiffness=1e3)  # wheelsets nearly free to yaw
    state = LinearisedRig(dataclasses.replace(reference_spec, parameters=free)).steady_curving(
        radius, 0.0, speed_m_s=speed
    )
    offsets = np.array([state["q"][f"wheelset_{a}.y"] for a in range(1, 5)])
    np.testing.assert_allclose(offsets, -pure, rtol=0.01)
    # the stiff primary yaw restraint of the reference bogie needs larger offsets to steer
    stiff = LinearisedRig(reference_spec).steady_curving(radius, 0.0, speed_m_s=speed)
    offsets = np.array([stiff["q"][f"wheelset_{a}.y"] for a in range(1, 5)])
    assert np.all(offsets < -1.5 * pure)


def test_flange_contact_when_the_curve_demands_it(reference_spec: RigSpec) -> None:
    speed, radius = 25.0, 600.0
    cant = balancing_cant_m(radius, speed)
    spec = reference_spec.with_simulation(speed_m_s=speed, duration_s=12.0, warm_up_s=8.0)
    linear = LinearisedRig(spec)
    state = linear.steady_curving(radius, cant)
    gap = spec.parameters["contact_flange_gap"]
    assert abs(state["dead_bands"]["flange_wheelset_1"]) > gap  # leading wheelset flanging
    design = _line(radius, cant * 1000, speed, 20.0, tangent_m=20.0)
    with pytest.raises(LinearModelNotApplicable, match="flange_wheelset_1"):
        linear.spectra(design=design)
    # PyBullet runs through the contact and settles on the same (nonlinear) steady state
    assembly = build_assembly(spec)
    forces = ForceModel(assembly)
    dt = spec.simulation.time_step_s
    t = np.arange(round(20.0 / dt) + 1) * dt
    profile = SpeedProfile.constant(speed, 20.0)
    terms, stroke0, _ = _design_start(spec, assembly, forces, design, profile, t, dt)
    zeros = np.zeros((4, t.size))
    world = VehicleWorld(dt)
    try:
        world.build(assembly)
        q, _ = integrate(
            world,
            forces,
            AxleExcitation(t, *([zeros] * 7)),
            np.full(t.size, speed),
            50,
            0.2,
            assembly.dof_names,
            terms,
            stroke0,
        )
    finally:
        world.close()
    expected = np.array([state["q"][name] for name in assembly.dof_names])
    wheelset = [i for i, name in enumerate(assembly.dof_names) if name.startswith("wheelset")]
    np.testing.assert_allclose(q[-1, wheelset], expected[wheelset], rtol=0.02, atol=2e-5)


def test_infinite_radius_leaves_tangent_track_spectra_unchanged(
    short_spec: RigSpec, short_track: TrackGeometry, reference_response: RigResponse
) -> None:
    flat = design_from_segments(
        [{"type": "curve", "length_m": short_track.length_m, "radius_m": 1e7, "direction": "left"}]
    )
    with Rig(short_spec) as rig:
        curved = rig.simulate(short_track, design=flat)
    difference = DB * (curved.spectra().log_amplitude - reference_response.spectra().log_amplitude)
    assert np.max(np.abs(difference)) < 0.01
    linear = LinearisedRig(short_spec)
    difference = DB * (linear.spectra(design=flat).log_amplitude - linear.spectra().log_amplitude)
    assert np.max(np.abs(difference)) < 0.01


def test_a_tangent_design_is_bit_for_bit_tangent_track(
    short_spec: RigSpec, short_track: TrackGeometry, reference_response: RigResponse
) -> None:
    straight = design_from_segments([{"type": "tangent", "length_m": short_track.length_m}])
    with Rig(short_spec) as rig:
        response = rig.simulate(short_track, design=straight)
    np.testing.assert_array_equal(
        response.accelerations_m_s2, reference_response.accelerations_m_s2
    )
    linear = LinearisedRig(short_spec)
    np.testing.assert_array_equal(
        linear.spectra(design=straight).log_amplitude, linear.spectra().log_amplitude
    )


def test_a_design_shorter_than_the_run_fails_before_any_step(
    short_spec: RigSpec, short_track: TrackGeometry
) -> None:
    short = design_from_segments([{"type": "tangent", "length_m": 100.0}])
    with Rig(short_spec) as rig, pytest.raises(DesignError, match="needs"):
        rig.simulate(short_track, design=short)
    with pytest.raises(DesignError, match="recorded stretch"):
        LinearisedRig(short_spec).spectra(design=short)


def test_linear_response_to_the_design_matches_pybullet(short_spec: RigSpec) -> None:
    """S-curve with transitions on smooth track: what remains after the removal, both ways."""
    from susp_bo.rig.linear_curving import design_signals
    from susp_bo.rig.state_space import state_space

    speed = short_spec.simulation.speed_m_s
    design = design_from_segments(
        [
            {"type": "tangent", "length_m": 200.0},
            {"type": "transition", "length_m": 250.0},
            {
                "type": "curve",
                "length_m": 600.0,
                "radius_m": 7000.0,
                "cant_mm": 150.0,
                "direction": "left",
            },
            {"type": "transition", "length_m": 250.0},
            {
                "type": "curve",
                "length_m": 1000.0,
                "radius_m": 7000.0,
                "cant_mm": 100.0,
                "direction": "right",
            },
        ]
    )
    with Rig(short_spec, linear_elements=True) as rig:
        response = rig.simulate(_smooth_track(2000.0), design=design)
    remaining = response.accelerations_m_s2 - response.quasi_static_m_s2
    assembly = build_assembly(short_spec)
    rate = short_spec.simulation.sample_rate_hz
    total = round(20.0 * rate)
    linear = design_signals(
        assembly,
        state_space(assembly, speed),
        design,
        speed,
        rate,
        total,
        short_spec.sensors,
        time_step_s=short_spec.simulation.time_step_s,
    )[:, round(4.0 * rate) :]
    for c, channel in enumerate(short_spec.channels):
        if channel.startswith("carbody"):  # roll-out and transition transients, ≈ 0.1 m/s²
            peak = np.max(np.abs(remaining[c]))
            assert np.max(np.abs(linear[c] - remaining[c])) < 0.05 * peak, channel


@pytest.mark.parametrize("speed", [math.nan, math.inf, -5.0])
def test_a_speed_that_is_not_one_is_refused(reference_spec: RigSpec, speed: float) -> None:
    # NaN/inf ended in "Newton did not converge", -5 m/s was taken as 5
    with pytest.raises(ValueError, match=r"speed_m_s: got .*; expected a finite speed >= 0"):
        LinearisedRig(reference_spec).steady_curving(4000.0, 0.1, speed_m_s=speed)
