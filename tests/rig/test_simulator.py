"""The PyBullet rig: input checks, determinism, stability over C_w, agreement with the
linearised model, time-step convergence, divergence reporting."""

from __future__ import annotations

import math

import numpy as np
import pytest

from susp_bo.rig.linear import LinearisedRig
from susp_bo.rig.response import RigResponse, SimulationFailed
from susp_bo.rig.simulator import Rig, synthetic_track
from susp_bo.rig.spec import RigSpec
from susp_bo.rig.spectra import SpectrumSettings
from susp_bo.rig.track import SpeedProfile, TrackGeometry

DB = 20.0 / math.log(10.0)


@pytest.fixture(scope="module")
def rig(short_spec: RigSpec):
    with Rig(short_spec) as shared:
        yield shared


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"speed": 0.0}, "speed"),
        ({"speed": -10.0}, "speed"),
        ({"speed": math.nan}, "speed"),
        ({"parameters": {"primary_vertical_stiffnes": 1.0}}, "unknown parameter"),
        ({"parameters": {"secondary_vertical_damping": 1e6}}, "admissible"),
        ({"parameters": {"bogie_mass": -2.0}}, "must be > 0"),
        ({"duration_s": 3.0}, "segment"),
        ({"duration_s": -1.0}, "duration"),
    ],
)
def test_bad_input_fails_before_any_simulation(
    rig: Rig, short_track: TrackGeometry, kwargs: dict, message: str
) -> None:
    with pytest.raises(ValueError, match=message):
        rig.simulate(short_track, **kwargs)


def test_too_short_track_and_band_beyond_nyquist_are_rejected(
    rig: Rig, short_spec: RigSpec
) -> None:
    short = TrackGeometry.synthetic(length_m=300.0, seed=0)
    with pytest.raises(ValueError, match="track"):
        rig.simulate(short)
    track = synthetic_track(short_spec, seed=0)
    with (
        Rig(short_spec.with_simulation(sample_rate_hz=25.0)) as coarse,
        pytest.raises(ValueError, match="Nyquist"),
    ):
        coarse.simulate(track)
    with pytest.raises(ValueError, match="finite"):
        TrackGeometry(0.25, *([np.array([0.0, math.nan, 0.0])] * 4))


def test_response_shape_and_plausible_levels(
    reference_response: RigResponse, short_spec: RigSpec
) -> None:
    r = reference_response
    assert r.channels == short_spec.channels
    assert r.sample_rate_hz == short_spec.simulation.sample_rate_hz
    assert r.accelerations_m_s2.shape == (len(r.channels), round(16.0 * r.sample_rate_hz))
    assert np.all(np.diff(r.time_s) > 0) and r.time_s[0] > short_spec.simulation.warm_up_s
    rms = r.accelerations_m_s2.std(axis=1)
    carbody = [rms[i] for i, c in enumerate(r.channels) if c.startswith("carbody")]
    bogie = [rms[i] for i, c in enumerate(r.channels) if c.startswith("bogie")]
    assert min(carbody) > 0.01 and max(carbody) < 1.0  # ride accelerations, m/s²
    assert min(bogie) > 3 * max(carbody)  # the suspension isolates the carbody


def test_same_seed_same_spectra_bit_for_bit(
    rig: Rig, short_spec: RigSpec, reference_response: RigResponse
) -> None:
    track = synthetic_track(short_spec, seed=11)
    again = rig.simulate(track)
    np.testing.assert_array_equal(again.accelerations_m_s2, reference_response.accelerations_m_s2)
    with Rig(short_spec) as fresh:
        third = fresh.simulate(track)
    np.testing.assert_array_equal(third.accelerations_m_s2, reference_response.accelerations_m_s2)
    np.testing.assert_array_equal(
        third.spectra().log_amplitude, reference_response.spectra().log_amplitude
    )
    other = rig.simulate(synthetic_track(short_spec, seed=12))
    assert not np.array_equal(other.accelerations_m_s2, reference_response.accelerations_m_s2)


def test_stable_at_the_extreme_corners_of_the_admissible_set(
    rig: Rig, short_track: TrackGeometry, short_spec: RigSpec
) -> None:
    low, high = short_spec.calibration_bounds
    for w in (low, high, np.where(np.arange(low.size) % 2 == 0, low, high)):
        response = rig.simulate(
            short_track, parameters=short_spec.parameters_from_vector(w), duration_s=8.0
        )
        assert np.all(np.isfinite(response.accelerations_m_s2))
        assert response.accelerations_m_s2.std(axis=1).max() < 10.0


def test_pybullet_agrees_with_the_linearised_model_on_the_same_track(
    short_spec: RigSpec, short_track: TrackGeometry
) -> None:
    with Rig(short_spec, linear_elements=True) as linear_rig:
        simulated = linear_rig.simulate(short_track)
    linear = LinearisedRig(short_spec).response(short_track, short_spec.simulation.speed_m_s)
    np.testing.assert_allclose(simulated.time_s, linear.time_s)
    deviation = DB * np.abs(simulated.spectra().log_amplitude - linear.spectra().log_amplitude)
    print(
        f"PyBullet vs linear: median {np.median(deviation):.3f} dB, "
        f"95th pct {np.percentile(deviation, 95):.3f} dB, max {deviation.max():.3f} dB"
    )
    assert np.median(deviation) < 0.2
    assert np.percentile(deviation, 95) < 1.0
    carbody = [i for i, c in enumerate(short_spec.channels) if c.startswith("carbody")]
    error = simulated.accelerations_m_s2[carbody] - linear.accelerations_m_s2[carbody]
    assert np.all(error.std(axis=1) < 0.1 * linear.accelerations_m_s2[carbody].std(axis=1))


def test_expected_spectra_of_the_fast_path_match_pybullet_statistically(
    short_spec: RigSpec, reference_response: RigResponse
) -> None:
    with Rig(short_spec, linear_elements=True) as linear_rig:
        simulated = linear_rig.simulate(synthetic_track(short_spec, seed=11))
    expected = LinearisedRig(short_spec).spectra()
    deviation = DB * (simulated.spectra().log_amplitude - expected.log_amplitude)
    # one 16 s record: Welch scatter of a few dB per band, but no bias
    assert abs(np.median(deviation)) < 1.0
    assert np.median(np.abs(deviation)) < 2.0


def test_halving_the_time_step_does_not_change_the_spectra(
    short_spec: RigSpec, short_track: TrackGeometry, reference_response: RigResponse
) -> None:
    with Rig(short_spec.with_simulation(time_step_s=short_spec.simulation.time_step_s / 2)) as r:
        fine = r.simulate(short_track)
    deviation = DB * np.abs(
        fine.spectra().log_amplitude - reference_response.spectra().log_amplitude
    )
    print(f"dt halving: median {np.median(deviation):.3f} dB, max {deviation.max():.3f} dB")
    assert np.median(deviation) < 0.1
    assert np.percentile(deviation, 95) < 0.5


def test_variable_speed_runs_and_changes_the_response(short_spec: RigSpec, rig: Rig) -> None:
    total = short_spec.simulation.warm_up_s + 12.0
    profile = SpeedProfile(np.array([0.0, total]), np.array([60.0, 80.0]))
    track = synthetic_track(short_spec, seed=5)
    response = rig.simulate(track, speed=profile)
    assert response.accelerations_m_s2.shape[1] == round(12.0 * response.sample_rate_hz)
    constant = rig.simulate(track, speed=60.0, duration_s=12.0)
    assert not np.allclose(response.accelerations_m_s2, constant.accelerations_m_s2)
    # a profile sets the run's length: a duration beside it was silently ignored
    with pytest.raises(ValueError, match=r"duration_s: got 5\.0 s with a SpeedProfile"):
        rig.simulate(track, speed=profile, duration_s=5.0)


def test_divergence_is_reported_not_returned(short_spec: RigSpec) -> None:
    # a conicity of 0.9 makes the wheelsets hunt at 83 m/s (a physical instability: the
    # time step is stable, so the run starts and the divergence check stops it)
    hunting = short_spec.with_parameters({"contact_equivalent_conicity": 0.9})
    with Rig(hunting) as r, pytest.raises(SimulationFailed) as failure:
        r.spectra(synthetic_track(hunting, seed=0))
    assert failure.value.reason.startswith("diverged at t = ")


def test_a_time_step_too_long_for_any_speed_is_refused_before_any_step(
    short_spec: RigSpec,
) -> None:
    # 10 ms is beyond the explicit stability limit of the bogie yaw mode (≈32 Hz): the run
    # diverged at t = 0.05 s; it is now refused before the first step, naming the step
    unstable = short_spec.with_simulation(time_step_s=0.01, warm_up_s=1.0)
    with Rig(unstable) as r, pytest.raises(SimulationFailed) as failure:
        r.spectra(synthetic_track(unstable, seed=0))
    assert "[simulation] time_step_s: 0.01 s is too long" in failure.value.reason


def test_a_speed_below_the_step_limit_is_refused_not_returned_as_noise(
    short_spec: RigSpec,
) -> None:
    # at 5 m/s the 2 ms step is unstable for the wheelset creep damping (minimum 7.91
    # m/s); PyBullet's joint-velocity clamp kept the run below the divergence limit and it
    # returned bogie accelerations of ~300 m/s² as if they were a response
    track = synthetic_track(short_spec.with_simulation(speed_m_s=5.0), seed=0)
    with Rig(short_spec) as r, pytest.raises(SimulationFailed) as failure:
        r.simulate(track, speed=5.0)
    assert "5 m/s is not allowed: below the minimum speed 7.91 m/s" in failure.value.reason
    slow = SpeedProfile(np.array([0.0, 20.0]), np.array([30.0, 6.0]))  # its slowest speed
    longer = synthetic_track(short_spec.with_simulation(speed_m_s=30.0), seed=0)
    with Rig(short_spec) as r, pytest.raises(SimulationFailed, match=r"slowest speed: 6 m/s"):
        r.simulate(longer, speed=slow)


def test_rig_spectra_use_the_rig_band(reference_response: RigResponse, short_spec: RigSpec) -> None:
    spectra = reference_response.spectra()
    np.testing.assert_allclose(spectra.frequencies_hz, short_spec.spectrum.frequencies_hz())
    coarse = reference_response.spectra(SpectrumSettings(1.0, 10.0, 8, 4.0))
    assert coarse.log_amplitude.shape == (len(short_spec.channels), 8)
