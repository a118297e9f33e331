"""The rig ``h_sim(x, w)``: PyBullet time integration, sensors, spectra.

Example:
    >>> from susp_bo.rig import Rig, synthetic_track
    >>> with Rig("hst_trailer") as rig:                               # doctest: +SKIP
    ...     track = synthetic_track(rig.spec, seed=1)
    ...     spectra = rig.spectra(track, parameters={"yaw_damper_damping": 3e6})

Every input is checked before the first step (parameters, speed, track length,
band vs Nyquist and record length); a run that diverges raises
:class:`SimulationFailed` with the reason instead of returning numbers, and so does,
before the first step, a run slower than the time step can simulate
(:mod:`susp_bo.rig.step_stability`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from operator import itemgetter
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from susp_bo.rig._pybullet import pybullet
from susp_bo.rig.assembly import Assembly, build_assembly
from susp_bo.rig.curving import (
    DesignInputs,
    design_inputs,
    reference_specific_force,
    steady_state,
)
from susp_bo.rig.design import TrackDesign
from susp_bo.rig.dynamics import ForceModel
from susp_bo.rig.response import RigResponse, SimulationFailed
from susp_bo.rig.sensors import sample_decimated
from susp_bo.rig.spec import RigSpec, load_rig_spec
from susp_bo.rig.spectra import Spectra, SpectrumSettings
from susp_bo.rig.step_stability import speed_problem
from susp_bo.rig.track import AxleExcitation, SpeedProfile, TrackGeometry, axle_excitation
from susp_bo.rig.world import VehicleWorld

FloatArray = NDArray[np.float64]
SpeedInput = float | SpeedProfile
__all__ = [
    "Rig",
    "RigResponse",
    "SimulationFailed",
    "axle_span_m",
    "excitation_for_run",
    "recorded_samples",
    "synthetic_track",
    "synthetic_track_length_m",
]


def _speed_profile(speed: SpeedInput, total_s: float) -> SpeedProfile:
    if isinstance(speed, SpeedProfile):
        return speed
    value = float(speed)
    if not (math.isfinite(value) and value > 0.0):
        raise ValueError(f"speed: got {speed!r} m/s; must be finite and > 0")
    return SpeedProfile.constant(value, total_s)


def excitation_for_run(
    assembly: Assembly,
    geometry: TrackGeometry,
    speed: SpeedInput,
    total_s: float,
    time_step_s: float,
    sample_rate_hz: float,
) -> tuple[AxleExcitation, int]:
    """Axle inputs at every step time ``0, dt, …, total_s`` and the steps per sample.

    Raises:
        ValueError: speed <= 0, a track too short for the run, bad timing.
    """
    profile = _speed_profile(speed, total_s)
    if profile.duration_s < total_s * (1 - 1e-12):
        raise ValueError(
            f"speed: the speed record lasts {profile.duration_s} s; the run needs {total_s} s"
        )
    n_steps = math.floor(total_s / time_step_s + 1e-9)  # never past the speed record
    per_sample = round(1.0 / (time_step_s * sample_rate_hz))
    n_steps -= n_steps % per_sample
    times = np.arange(n_steps + 1) * time_step_s
    excitation = axle_excitation(geometry, profile, assembly.axle_positions_m, times)
    periodic = assembly.periodic_inputs
    if periodic.size:  # deterministic inputs (wheel out-of-roundness) on the vertical inputs
        n_axles = excitation.n_axles
        n_in = 3 * n_axles
        distance = profile.distance_m(times)
        values = periodic.values(distance, n_in).reshape(n_axles, 3, -1)
        rates = periodic.rates(distance, profile.speed_at(times), n_in).reshape(n_axles, 3, -1)
        if np.any(values[:, 1:]):
            raise ValueError("periodic inputs: only vertical axle inputs are supported")
        excitation = dataclasses.replace(
            excitation,
            vertical_m=excitation.vertical_m + values[:, 0],
            vertical_rate_m_s=excitation.vertical_rate_m_s + rates[:, 0],
        )
    return excitation, per_sample


def axle_span_m(spec: RigSpec) -> float:
    """Distance from the rearmost to the leading axle (m): 2 (bogie pivot + wheelbase halves)."""
    return 2.0 * (
        spec.parameters["bogie_half_pivot_spacing"] + spec.parameters["bogie_half_wheelbase"]
    )


def synthetic_track(
    spec: RigSpec,
    seed: int,
    speed_m_s: float | None = None,
    duration_s: float | None = None,
    quality: str | None = None,
) -> TrackGeometry:
    """A German-PSD track long enough for one default run of ``spec`` (seeded)."""
    length = synthetic_track_length_m(spec, speed_m_s, duration_s)
    return TrackGeometry.synthetic(
        quality=quality or spec.simulation.track_quality, length_m=length, seed=seed
    )


def synthetic_track_length_m(
    spec: RigSpec, speed_m_s: float | None = None, duration_s: float | None = None
) -> float:
    """Length (m) of :func:`synthetic_track`: the run, the axle span and 10 m to spare."""
    sim = spec.simulation
    speed = sim.speed_m_s if speed_m_s is None else speed_m_s
    duration = sim.duration_s if duration_s is None else duration_s
    return speed * (sim.warm_up_s + duration) + axle_span_m(spec) + 10.0


def recorded_samples(spec: RigSpec, total_s: float) -> tuple[float, int, float]:
    """What :meth:`Rig.simulate` records of a run whose speed record lasts ``total_s`` (s).

    Returns:
        ``(first_s, n, interval_s)``: the time of the first recorded sample on the speed
        record's clock (s; samples are boxcar means labelled at their interval's centre,
        so ``first_s`` is half an interval after the warm-up's end), the number of samples
        and the sample interval (s). The same integer rounding as the simulation's step
        grid (:func:`excitation_for_run`) and its warm-up cut.
    """
    sim = spec.simulation
    per_sample = round(1.0 / (sim.time_step_s * sim.sample_rate_hz))
    n_steps = math.floor(total_s / sim.time_step_s + 1e-9)
    interval = per_sample * sim.time_step_s
    start = round(sim.warm_up_s / interval)
    return (start + 0.5) * interval, n_steps // per_sample - start, interval


def integrate(
    world: VehicleWorld,
    forces: ForceModel,
    excitation: AxleExcitation,
    speed_m_s: FloatArray,
    record_every: int,
    limit: float,
    names: tuple[str, ...],
    design: DesignInputs | None = None,
    stroke0: FloatArray | None = None,
) -> tuple[FloatArray, FloatArray]:
    """Step the world through the excitation; states every ``record_every`` steps.

    Args:
        world: a built world (state at rest or set by the caller).
        forces: the force model of the same assembly.
        excitation: inputs at the step times (n_steps + 1 samples).
        speed_m_s: speed at the step times (n_steps + 1,).
        record_every: steps between recorded states.
        limit: divergence threshold on |q| (m or rad).
        names: coordinate names for messages.
        design: the terms of a track design at the step times (curved line), or None.
        stroke0: initial series-damper strokes (n_s,) m; default zeros.

    Returns:
        ``(q, q̇)`` each (n_records x n) at steps 0, record_every, …, n_steps.

    Raises:
        SimulationFailed: non-finite state or |q| beyond ``limit``.
    """
    n_in = excitation.n_axles * 3
    x_all = np.empty((excitation.time_s.size, n_in))
    xd_all = np.empty_like(x_all)
    for c, (value, rate) in enumerate(
        (
            ("vertical_m", "vertical_rate_m_s"),
            ("cross_level_rad", "cross_level_rate_rad_s"),
            ("alignment_m", "alignment_rate_m_s"),
        )
    ):
        x_all[:, c::3] = getattr(excitation, value).T
        xd_all[:, c::3] = getattr(excitation, rate).T
    n_steps = excitation.time_s.size - 1
    dt = world.time_step_s
    client = world.client._client  # raw pybullet calls: no per-call wrapper overhead
    body, joints = world.body_id, world.joints
    get_states = pybullet.getJointStates
    set_torques = pybullet.setJointMotorControlArray
    step = pybullet.stepSimulation
    position_of, velocity_of, n_joints = itemgetter(0), itemgetter(1), len(joints)
    torque = pybullet.TORQUE_CONTROL
    stroke = np.zeros(forces.n_strokes) if stroke0 is None else np.array(stroke0, dtype=float)
    if design is not None:
        offsets, rates = design.offsets, design.rates
        loads = design.loads + forces.design_forces(offsets, rates)
    records = n_steps // record_every + 1
    q_out = np.empty((records, forces.n))
    qd_out = np.empty((records, forces.n))
    for j in range(n_steps + 1):
        states = get_states(body, joints, physicsClientId=client)
        q = np.fromiter(map(position_of, states), np.float64, n_joints)
        qd = np.fromiter(map(velocity_of, states), np.float64, n_joints)
        if j % record_every == 0:
            k = j // record_every
            q_out[k], qd_out[k] = q, qd
            worst = np.max(np.abs(q))
            if not (np.isfinite(worst) and np.all(np.isfinite(qd)) and worst <= limit):
                index = int(np.argmax(np.where(np.isfinite(q), np.abs(q), np.inf)))
                raise SimulationFailed(
                    f"diverged at t = {j * dt:.3f} s: {names[index]} = {q[index]:.4g} "
                    f"(limit {limit} m or rad)"
                )
        if j == n_steps:
            break
        if design is None:
            generalised, stroke_rate = forces(q, qd, x_all[j], xd_all[j], speed_m_s[j], stroke)
        else:
            generalised, stroke_rate = forces(
                q, qd, x_all[j], xd_all[j], speed_m_s[j], stroke, offsets[j], rates[j]
            )
            generalised += loads[j]
        stroke += dt * stroke_rate
        set_torques(body, joints, torque, forces=generalised.tolist(), physicsClientId=client)
        step(physicsClientId=client)
    return q_out, qd_out


class Rig:
    """The vehicle rig: one PyBullet DIRECT client, many runs.

    Args:
        spec: a rig spec, or a rig name / path for :func:`load_rig_spec`.
        linear_elements: use the slopes of every nonlinear element (for the
            cross-check against :class:`~susp_bo.rig.linear.LinearisedRig`).
    """

    def __init__(self, spec: RigSpec | str | Path, linear_elements: bool = False) -> None:
        self.spec = spec if isinstance(spec, RigSpec) else load_rig_spec(spec)
        self.linear_elements = linear_elements
        self._world: VehicleWorld | None = VehicleWorld(self.spec.simulation.time_step_s)

    @property
    def channels(self) -> tuple[str, ...]:
        """Sensor channel names (C,)."""
        return self.spec.channels

    @property
    def parameter_names(self) -> tuple[str, ...]:
        """The calibration parameter names (q,)."""
        return self.spec.calibration_names

    def __enter__(self) -> Rig:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Release the PyBullet client (idempotent)."""
        if self._world is not None:
            self._world.close()
            self._world = None

    def simulate(
        self,
        geometry: TrackGeometry,
        speed: SpeedInput | None = None,
        parameters: Mapping[str, float] | None = None,
        duration_s: float | None = None,
        design: TrackDesign | None = None,
    ) -> RigResponse:
        """Run the vehicle over a track and record the sensors.

        Args:
            geometry: the track (irregularities).
            speed: constant speed (m/s) or a :class:`SpeedProfile` (its duration is the
                run, warm-up included); default the rig's speed.
            parameters: named parameter values (validated against C_w).
            duration_s: recorded time after the warm-up (s); default the rig's.
            design: the line's design (curves, cant, gradient) on the geometry's
                chainage; None is tangent track (bit-for-bit the tangent-track code
                path). The run starts from the quasi-static curving state at t = 0
                (:func:`~susp_bo.rig.curving.steady_state`); the response carries the
                design's quasi-static specific force, removed before the spectra.

        Returns:
            The response after the warm-up.

        Raises:
            ValueError: bad input (detected before any step).
            SimulationFailed: divergence; or, before any step, a run slower than the
                time step can simulate (:mod:`susp_bo.rig.step_stability`: it would
                diverge, or return meaningless signals where PyBullet's clamp on joint
                velocities holds it below the divergence limit).
        """
        if self._world is None:
            raise RuntimeError("Rig: closed")
        spec = self.spec.with_parameters(parameters)
        sim = spec.simulation
        speed = sim.speed_m_s if speed is None else speed
        if isinstance(speed, SpeedProfile):
            if duration_s is not None:  # the profile sets the run's length: two would disagree
                raise ValueError(
                    f"duration_s: got {duration_s} s with a SpeedProfile; a profile's "
                    f"duration ({speed.duration_s} s, warm-up included) is the run's length: "
                    "leave duration_s out, or make the profile that long"
                )
            total = speed.duration_s
            duration = total - sim.warm_up_s
        else:
            duration = sim.duration_s if duration_s is None else float(duration_s)
            total = sim.warm_up_s + duration
        if not duration > 0:
            raise ValueError(f"duration_s: got {duration} s after the warm-up; must be > 0")
        spec.spectrum.check_sample_rate(sim.sample_rate_hz, duration)
        assembly = build_assembly(spec)
        excitation, per_sample = excitation_for_run(
            assembly, geometry, speed, total, sim.time_step_s, sim.sample_rate_hz
        )
        profile = _speed_profile(speed, total)
        speeds = profile.speed_at(excitation.time_s)
        unstable = speed_problem(spec, float(np.min(speeds)), assembly, "the run's slowest speed")
        if unstable is not None:  # before any step: the step would diverge
            raise SimulationFailed(unstable)
        forces = ForceModel(assembly, self.linear_elements)
        terms, stroke0, q0 = None, None, None
        if design is not None:
            terms, stroke0, q0 = _design_start(
                spec, assembly, forces, design, profile, excitation.time_s, sim.time_step_s
            )
        self._world.build(assembly)
        if q0 is not None:
            self._world.set_state(list(q0), [0.0] * len(q0))
        q, qd = integrate(
            self._world,
            forces,
            excitation,
            speeds,
            per_sample,
            sim.max_displacement_m,
            assembly.dof_names,
            terms,
            stroke0,
        )
        start = round(sim.warm_up_s / (sim.time_step_s * per_sample))
        time, signals = sample_decimated(
            assembly, q[start:], qd[start:], per_sample * sim.time_step_s
        )
        time = time + start * per_sample * sim.time_step_s
        quasi_static = None
        if terms is not None:
            recorded = terms.sensors[::per_sample][start:]  # (n_k x C) at the record steps
            signals = signals + (0.5 * (recorded[1:] + recorded[:-1])).T
            quasi_static = reference_specific_force(assembly, spec.sensors, design, profile, time)
        return RigResponse(
            time,
            assembly.channels,
            signals,
            sim.sample_rate_hz,
            spec.spectrum,
            quasi_static_m_s2=quasi_static,
        )

    def spectra(
        self,
        geometry: TrackGeometry,
        speed: SpeedInput | None = None,
        parameters: Mapping[str, float] | None = None,
        settings: SpectrumSettings | None = None,
        design: TrackDesign | None = None,
    ) -> Spectra:
        """Log-amplitude spectra of a run (settings default to the rig's).

        With a ``design``, the design's quasi-static specific force is removed from
        the signals first (:meth:`RigResponse.spectra`).
        """
        return self.simulate(geometry, speed, parameters, design=design).spectra(settings)


def _design_start(
    spec: RigSpec,
    assembly: Assembly,
    forces: ForceModel,
    design: TrackDesign,
    profile: SpeedProfile,
    times: FloatArray,
    time_step_s: float,
) -> tuple[DesignInputs, FloatArray, FloatArray]:
    """Design terms at the step times, initial strokes and the quasi-static start state.

    Raises:
        ValueError: the design does not cover every body and sensor over the run.
    """
    rear = float(np.min(assembly.axle_positions_m))
    car = -rear + profile.distance_m(times)  # rearmost axle at s = 0 at t = 0
    xs = [float(b.cg_m[0]) for b in assembly.bodies] + [s.position_m[0] for s in spec.sensors]
    design.check_covers(float(car[0] + min(xs)), float(car[-1] + max(xs)))
    terms = design_inputs(assembly, design, car, profile.speed_at(times), time_step_s, spec.sensors)
    q0, _ = steady_state(assembly, terms.offsets[0], terms.loads[0])
    z0 = np.concatenate([q0, np.zeros(assembly.n_inputs)]) + terms.offsets[0]
    return terms, forces.series_positions(z0), q0
