"""The measured samples a study compares: the stretch of record the simulation records.

A simulation of a measured run (:meth:`susp_bo.rig.simulator.Rig.simulate`) runs the run's
whole speed record from rest and records after the rig's warm-up
(``simulation.warm_up_s``): samples from ``warm_up_s`` to the end of the speed record
(:func:`susp_bo.rig.simulator.recorded_samples`). The measured spectra must come from the
same stretch of track, to the sample: Welch's segments must fall on the same samples, and
half a second of offset costs a paired study hundreds of standard deviations of log L at
the true parameters (session 35, the fast rig; one sample of shift costs 0.002 rms of
log amplitude, about the sensor noise of a bogie channel).

Runs made by ``susp-bo synth`` (and the demo) start at the warm-up's end and stop at the
speed record's, so they are compared whole, bit for bit as before. An imported run
(``susp-bo import csv ... --speed 20``, a ``.mat`` file with a constant speed) starts at
t = 0 on its clock: its first ``warm_up_s`` seconds have no simulated counterpart and
are left out (:func:`compared_window`). What cannot be aligned is refused before any
simulation, naming the file, the two windows and what to change:

- accelerations that start after the simulated record does (the simulation would see
  track the measurement never saw);
- accelerations that stop before the speed record ends (the simulation runs on to the
  record's end).
"""

from __future__ import annotations

import dataclasses
import math

from susp_bo.data.measured import MeasuredRun
from susp_bo.data.run_validation import record_end_s
from susp_bo.rig.simulator import axle_span_m, recorded_samples
from susp_bo.rig.spec import RigSpec

TOLERANCE_SAMPLES = 0.5
"""How far (in measured samples) the measured record may start after the simulated one:
half a sample, the labelling ambiguity of a sampled record."""


class RecordWindowError(ValueError):
    """A measured run whose accelerations do not cover the stretch the simulation records."""


def compared_window(run: MeasuredRun, spec: RigSpec, source: str) -> MeasuredRun:
    """``run`` with the accelerations the simulation of it records, and no others.

    Args:
        run: a measured run (its speed record sets the simulated run's length).
        spec: the rig (its warm-up, time step and sample rate).
        source: the run's file, for the message.

    Returns:
        ``run`` itself when its record is the simulated one (synthetic runs); otherwise a
        copy holding the samples nearest the simulated record's first time, as many as
        the simulated record lasts at the run's sample rate (its ``time_offset_s``
        moved accordingly). Its content digest is not the run's: identify the run by the
        original.

    Raises:
        RecordWindowError: the accelerations start more than half a sample after the
            simulated record or stop before it, or what is left is too short for the
            spectra (or the warm-up leaves fewer than 2 samples).
    """
    first_s, n_simulated, interval_s = recorded_samples(spec, run.speed.duration_s)
    rate = run.sample_rate_hz
    count = round(n_simulated * interval_s * rate)
    # the centre of the first measured-rate sample inside the simulated record's first
    # interval (its first label itself when the run is sampled at the rig's rate)
    anchor_s = first_s - 0.5 * interval_s + 0.5 / rate
    offset = (anchor_s - run.time_offset_s) * rate  # measured samples before the record
    # the nearest sample, half-way rounded down: a record labelled at its intervals' starts
    # (5.00, 5.01, …) against the simulation's centres (5.005, …) is the same record
    start = max(0, math.ceil(offset - 0.5 - 1e-9))
    last_s = record_end_s(run)
    simulated_end_s = first_s + (n_simulated - 1) * interval_s
    warm_up = spec.simulation.warm_up_s
    where = (
        f"{source}: its accelerations cover {run.time_offset_s:.10g} … {last_s:.10g} s on its "
        f"speed record's clock, but the rig simulates this run over its whole speed record "
        f"(0 … {run.speed.duration_s:.10g} s) and records after its warm-up of "
        f"{warm_up:.10g} s: {first_s:.10g} … {simulated_end_s:.10g} s; the measured and "
        "simulated spectra must come from the same stretch of track"
    )
    if n_simulated < 2:
        raise RecordWindowError(
            f"{where}: the speed record ends before the warm-up leaves 2 samples; give a "
            "longer run, or lower the rig's simulation.warm_up_s"
        )
    if offset < -TOLERANCE_SAMPLES:
        raise RecordWindowError(
            f"{where}: the accelerations start after the simulated record; set the rig's "
            f"simulation.warm_up_s to {run.time_offset_s:.10g} s (at most the first "
            "sample's time), or give a speed record that starts warm_up_s before the first "
            "sample"
        )
    if start + count > run.n_samples:
        raise RecordWindowError(
            f"{where}: the speed record runs on after the last acceleration sample; cut it "
            f"to end at the last sample ({last_s:.10g} s)"
        )
    try:
        spec.spectrum.check_sample_rate(rate, count / rate)
    except ValueError as error:
        raise RecordWindowError(
            f"{where}: what is left after the warm-up ({count / rate:.10g} s) is too short "
            f"for the spectra ({error}); give a longer run, or lower the rig's "
            "simulation.warm_up_s"
        ) from None
    if start == 0 and count == run.n_samples:
        return run
    return dataclasses.replace(
        run,
        accelerations_m_s2=run.accelerations_m_s2[:, start : start + count],
        time_offset_s=run.time_offset_s + start / rate,
    )


def simulated_track_m(run: MeasuredRun, spec: RigSpec) -> float:
    """Track (m) a simulation of ``run`` covers: the distance of its whole speed record
    (warm-up included) plus the rig's axle span."""
    return float(run.speed.distance_m(run.speed.duration_s)) + axle_span_m(spec)


def check_track_covers_the_speed_record(run: MeasuredRun, spec: RigSpec, source: str) -> None:
    """Refuses a measured track shorter than the simulation of its run needs.

    :func:`susp_bo.data.run_validation.validate_run` checks the track against the last
    acceleration sample; the simulation runs to the end of the speed record, which may
    end later (by half a sample after :func:`compared_window`), so a track that only just
    covers the accelerations would fail every simulation of the run. A run without
    geometry passes (its track is not simulated).

    Raises:
        RecordWindowError: naming the file, the two lengths and the speed record.
    """
    if run.geometry is None:
        return
    span = axle_span_m(spec)
    needed = simulated_track_m(run, spec)
    if needed > run.geometry.length_m * (1 + 1e-9):
        raise RecordWindowError(
            f"{source}: track shorter than its simulation: the geometry covers "
            f"{run.geometry.length_m:g} m, but the rig simulates the whole speed record "
            f"(0 … {run.speed.duration_s:g} s), {needed - span:g} m (+ axle span {span:g} m) "
            f"= {needed:g} m; give a longer track, or cut the speed record to end at the "
            "last acceleration sample"
        )
