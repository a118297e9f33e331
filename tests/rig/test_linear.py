"""Linearised model: modal frequencies vs the published ranges, stability over C_w, notches."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from scipy.signal import argrelmin

from susp_bo.rig.linear import LinearisedRig
from susp_bo.rig.simulator import recorded_samples, synthetic_track
from susp_bo.rig.spec import RigSpec, load_rig_spec
from susp_bo.rig.spectra import SpectrumSettings
from susp_bo.rig.track import TrackGeometry, TrackPSD

# Published ranges of uncoupled modes for high-speed passenger cars (shared/DESIGN.md:
# carbody bounce 0.6-1.1, pitch 0.9-1.3, lateral ≈0.6; bogie bounce ≈7, pitch ≈12 Hz).
PUBLISHED_HZ = {
    "carbody_bounce": (0.6, 1.1),
    "carbody_pitch": (0.9, 1.3),
    "carbody_lateral": (0.45, 0.75),
    "carbody_roll": (0.8, 1.6),
    "bogie_bounce": (6.0, 8.0),
    "bogie_pitch": (10.0, 14.0),
}


@pytest.fixture(scope="module")
def linear(reference_spec: RigSpec) -> LinearisedRig:
    return LinearisedRig(reference_spec)


def test_modal_frequencies_fall_in_the_published_ranges(linear: LinearisedRig) -> None:
    modes = linear.modal_frequencies_hz()
    print({k: round(v, 3) for k, v in modes.items()})
    for name, (low, high) in PUBLISHED_HZ.items():
        assert low <= modes[name] <= high, (name, modes[name])


def test_carbody_bounce_and_bogie_pitch_match_hand_calculations(
    linear: LinearisedRig, reference_spec: RigSpec
) -> None:
    p = reference_spec.parameters
    primary = 2 * p["primary_vertical_stiffness"] * 2  # per bogie: 4 axleboxes
    secondary = 2 * p["secondary_vertical_stiffness"]  # per bogie: 2 air springs
    series = 1.0 / (1.0 / primary + 1.0 / secondary)  # bogie mass neglected
    bounce = math.sqrt(2 * series / p["carbody_mass"]) / (2 * math.pi)
    modes = linear.modal_frequencies_hz()
    assert modes["carbody_bounce"] == pytest.approx(bounce, rel=0.03)
    pitch_stiffness = 4 * p["primary_vertical_stiffness"] * p["bogie_half_wheelbase"] ** 2
    lever = p["primary_height"] - p["bogie_cg_height"]  # longitudinal springs below the cg
    pitch_stiffness += 4 * p["primary_longitudinal_stiffness"] * lever**2
    pitch = math.sqrt(pitch_stiffness / p["bogie_pitch_inertia"]) / (2 * math.pi)
    assert modes["bogie_pitch"] == pytest.approx(pitch, rel=0.03)


def test_linear_model_is_stable_at_every_corner_of_the_admissible_set(
    linear: LinearisedRig, reference_spec: RigSpec
) -> None:
    low, high = reference_spec.calibration_bounds
    worst = -np.inf
    for corner in itertools.product((0, 1), repeat=low.size):
        w = np.where(np.array(corner) == 1, high, low)
        worst = max(worst, linear.eigenvalues(reference_spec.parameters_from_vector(w)).real.max())
    assert worst < -0.05


def test_damped_modes_agree_with_the_eigenvalues_and_the_undamped_frequencies(
    linear: LinearisedRig,
) -> None:
    """Each oscillatory mode is one eigenvalue pair λ = -ζω ± iω√(1-ζ²) of the state
    matrix; the carbody bounce, nearly uncoupled (energy share > 0.99), has |λ| close to
    the undamped uncoupled frequency (a single degree of freedom's |λ| is ω_n exactly)."""
    modes = linear.modes()
    eigenvalues = linear.eigenvalues()
    upper = eigenvalues[eigenvalues.imag > 1e-6]
    assert len(modes) == upper.size
    frequencies = [m.frequency_hz for m in modes]
    assert frequencies == sorted(frequencies)
    for mode in modes:
        assert 0.0 < mode.damping_ratio < 1.0 and 0.0 < mode.energy_share <= 1.0
        rebuilt = (
            2
            * np.pi
            * mode.frequency_hz
            * complex(-mode.damping_ratio, math.sqrt(1 - mode.damping_ratio**2))
        )
        assert np.min(np.abs(upper - rebuilt)) <= 1e-8 * abs(rebuilt)
    bounce = next(m for m in modes if m.name == "carbody_bounce")
    assert bounce.energy_share > 0.99
    undamped = linear.modal_frequencies_hz()["carbody_bounce"]
    assert bounce.frequency_hz == pytest.approx(undamped, rel=0.05)


def test_second_rig_is_stable_and_has_its_own_modes() -> None:
    spec = load_rig_spec("manchester_benchmark")
    modes = LinearisedRig(spec).modal_frequencies_hz()
    assert 0.6 <= modes["carbody_bounce"] <= 1.3
    assert 5.0 <= modes["bogie_bounce"] <= 9.0
    assert LinearisedRig(spec).eigenvalues().real.max() < 0


def test_bogie_spacing_notches_appear_where_geometry_puts_them(
    linear: LinearisedRig, reference_spec: RigSpec
) -> None:
    speed = reference_spec.simulation.speed_m_s
    half_pivot = reference_spec.parameters["bogie_half_pivot_spacing"]
    f = np.linspace(1.0, 13.0, 1200)
    mid = reference_spec.channels.index("carbody_mid_vertical")
    psd = linear.psd(f, components=("vertical",))[:, mid]
    minima = f[argrelmin(np.log(psd), order=15)[0]]
    # mid-car bounce input ∝ cos(ω a / V): zeros at f = (2k + 1) V / (4 a)
    for k in range(3):
        expected = (2 * k + 1) * speed / (4 * half_pivot)
        assert np.min(np.abs(minima - expected)) < 0.02 * expected, (expected, minima)
        depth = np.log(
            psd[np.argmin(np.abs(f - expected))] / psd[np.argmin(np.abs(f - 1.2 * expected))]
        )
        assert depth < -2.0  # more than 8.7 dB deep


def test_fast_path_spectra_are_finite_and_quick(
    linear: LinearisedRig, reference_spec: RigSpec
) -> None:
    spectra = linear.spectra()
    assert spectra.log_amplitude.shape == (
        len(reference_spec.channels),
        reference_spec.spectrum.n_frequencies,
    )
    rougher = linear.spectra(psd=TrackPSD("high"))
    # amplitude scales with sqrt(A_v): high/low roughness = sqrt(1.08e-6/4.032e-7) vertically
    mid = reference_spec.channels.index("carbody_mid_vertical")
    ratio = np.median(rougher.log_amplitude[mid] - spectra.log_amplitude[mid])
    assert ratio == pytest.approx(0.5 * math.log(1.08e-6 / 4.032e-7), abs=0.1)


def test_fast_path_spectra_refuse_a_band_above_nyquist_and_a_psd_name(
    linear: LinearisedRig, reference_spec: RigSpec
) -> None:
    """f_max above the rig's Nyquist gave spectra no recording can hold (MeasuredRun.spectra
    refuses the same settings); a string psd was an AttributeError deep in the model."""
    nyquist = 0.5 * reference_spec.simulation.sample_rate_hz
    with pytest.raises(ValueError, match=r"settings: sample_rate_hz: .* Nyquist"):
        linear.spectra(settings=SpectrumSettings(f_max_hz=1.2 * nyquist))
    with pytest.raises(TypeError, match="psd: 'low'"):
        linear.spectra(psd="low")  # type: ignore[arg-type]


def test_a_reused_state_space_gives_the_fresh_rigs_response_bit_for_bit(
    short_spec: RigSpec, short_track: TrackGeometry
) -> None:
    """The rig keeps its last state space and modal basis (the ν runs of one parameter
    point share them): interleaved parameter points and tracks give exactly what a fresh
    rig computes, and a changed parameter, speed or dead-band slope is never a hit."""
    other_track = synthetic_track(short_spec, seed=12)
    speed = short_spec.simulation.speed_m_s
    points = [None, {"secondary_vertical_damping": 25.0e3}, None, {"yaw_damper_damping": 3.0e6}]
    shared = LinearisedRig(short_spec)
    for parameters in points:
        for track in (short_track, other_track):
            reused = shared.response(track, speed, parameters).accelerations_m_s2
            fresh = LinearisedRig(short_spec).response(track, speed, parameters)
            np.testing.assert_array_equal(reused, fresh.accelerations_m_s2)
    system = shared._system(None, speed)
    assert shared._system({}, speed) is system  # the same point, said another way
    assert shared._system({"secondary_vertical_damping": 25.0e3}, speed) is not system
    assert shared._system(None, speed + 1.0).a.tolist() != system.a.tolist()
    slopes = np.zeros(len(system.assembly.dead_bands.group.names))
    with_slopes = shared._system(None, speed, slopes)
    assert shared._system(None, speed, slopes) is with_slopes
    assert shared._system(None, speed, slopes + 1.0e5) is not with_slopes


@pytest.mark.parametrize(("warm_up_s", "total_s"), [(1.0, 9.0), (1.013, 9.0037), (0.995, 8.996)])
def test_the_linear_response_records_what_the_simulation_records(
    fast_rig, warm_up_s: float, total_s: float
) -> None:
    """The fast path (the discrepancy workflow's linear simulator: the whole speed record
    at the output rate, recorded after the warm-up) has the same samples as
    :meth:`Rig.simulate` (:func:`~susp_bo.rig.simulator.recorded_samples`), warm-ups and
    records on and off the sample grid: its spectra and a measured run's compared window
    are over the same samples."""
    spec = load_rig_spec(fast_rig).with_simulation(warm_up_s=warm_up_s)
    rate = spec.simulation.sample_rate_hz
    response = LinearisedRig(spec).response(
        synthetic_track(spec, seed=1),
        80.0,
        duration_s=total_s - warm_up_s,
        time_step_s=1.0 / rate,
    )
    first_s, n, interval_s = recorded_samples(spec, total_s)
    assert response.accelerations_m_s2.shape[1] == response.time_s.size == n
    assert response.time_s[0] == pytest.approx(first_s, abs=1e-9)
    assert np.diff(response.time_s) == pytest.approx(np.full(n - 1, interval_s))
